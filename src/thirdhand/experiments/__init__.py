"""Experiments: the tables the docs print, as functions returning their figures.

Not part of any stage; each module is imported by the command or script that
prints its table (``thirdhand experiment …``, ``scripts/*.py``) and by the tests.

- :mod:`~thirdhand.experiments.constraint_sweep`: synthetic sweeps of the
  constraint fits (accuracy by condition, axis errors, confidence calibration).
- :mod:`~thirdhand.experiments.execution`: execution with and without free-DOF
  goal sampling, on seeded learned tasks.
- :mod:`~thirdhand.experiments.plan_accuracy`: constraint pose error, plan
  success and corrections on synthetic scenes, beside the 3rdHand report.
- :mod:`~thirdhand.experiments.primitive_library`: the primitive-library
  parser's experiments (sine, LASA joins, DP checks, scaling, orientations).
- :mod:`~thirdhand.experiments.relational_irl`: the relational IRL tables
  (noise, data size, dynamics change, transfer, chair) beside the RCSI paper.
- :mod:`~thirdhand.experiments.relational_large`: rewards learned on small
  worlds, planned on large ones.

Scores shared with the stages' reports are in :mod:`thirdhand.metrics`.
"""
