"""Experiments: the tables the docs print, as functions returning their figures.

Not part of any stage; each module is imported by the command or script that
prints its table (``thirdhand experiment …``, ``scripts/*.py``) and by the tests.

- :mod:`~thirdhand.experiments.constraint_sweep`: synthetic sweeps of the
  constraint fits (accuracy by condition, axis errors, confidence calibration).
- :mod:`~thirdhand.experiments.plan_accuracy`: constraint pose error, plan
  success and corrections on synthetic scenes, beside the 3rdHand report.
- :mod:`~thirdhand.experiments.primitive_library`: the primitive-library
  parser's experiments (sine, LASA joins, DP checks, scaling, orientations).

The execution sweep and the relational-IRL tables are still beside their stage
(:mod:`thirdhand.execute.experiments`, :mod:`thirdhand.relational.experiments`).
"""
