"""Small data sets with known truth, for tests, benchmarks and experiments.

Not part of any stage: no stage module imports them (a command that needs one,
such as ``primitives`` reading a LASA ``.mat``, imports it when it runs).

- :mod:`~thirdhand.datasets.joint_tracks`: random relative-pose tracks of known
  joints (fixed, prismatic, revolute, cylindrical, screw, free) under tracker
  errors.
- :mod:`~thirdhand.datasets.pick_place`: small pick-and-place recordings with
  known interaction intervals.
- :mod:`~thirdhand.datasets.primitive_shapes`: sine skills with known cuts and
  LASA handwriting shapes joined end to start (``../shared/data/lasa``).

The full synthetic assembly scenes are :mod:`thirdhand.synth`.
"""
