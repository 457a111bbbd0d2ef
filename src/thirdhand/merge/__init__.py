"""Several capture systems in one recording: ``thirdhand merge A B … -o OUT``.

:mod:`~thirdhand.merge.align` estimates how a recording maps onto a reference
(clock offset and drift from the motion of shared bodies, the rigid transform
between the world frames by robust Kabsch over simultaneous samples);
:mod:`~thirdhand.merge.combine` resamples the aligned recordings onto one time
axis, gaps kept as gaps; :mod:`~thirdhand.merge.cli` is the command.
"""

from thirdhand.merge.align import Alignment, BodyResidual, MergeError, align
from thirdhand.merge.combine import combine, merge, rename

__all__ = ["Alignment", "BodyResidual", "MergeError", "align", "combine", "merge", "rename"]
