"""Experiments: the tables the docs print, as functions returning their figures.

Not part of any stage; each module is imported by the command or script that
prints its table (``python -m research experiment …``, ``research/scripts/*.py``) and by the tests.

- :mod:`~research.constraint_sweep`: synthetic sweeps of the
  constraint fits (accuracy by condition, axis errors, confidence calibration).
- :mod:`~research.execution`: execution with and without free-DOF
  goal sampling, on seeded learned tasks.
- :mod:`~research.plan_accuracy`: constraint pose error, plan
  success and corrections on synthetic scenes, beside the 3rdHand report.
- :mod:`~research.primitive_library`: the primitive-library
  parser's experiments (sine, LASA joins, DP checks, scaling, orientations).
- :mod:`~research.relational_irl`: the relational IRL tables
  (noise, data size, dynamics change, transfer, chair) beside the RCSI paper.
- :mod:`~research.relational_large`: rewards learned on small
  worlds, planned on large ones.

Scores shared with the stages' reports are in :mod:`thirdhand.metrics`.
"""
