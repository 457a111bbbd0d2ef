"""Motor primitives: DMPs (position and orientation), ProMPs, alignment, the primitive library.

::

    from thirdhand.primitives import DMP, HiddenSemiMarkov, PoseDMP, ProMP, PrimitiveLibrary

    dmp = PoseDMP(30).fit(t, pos, quat)                  # child in parent frame
    s, p, q = dmp.rollout(start_pos=new_start)           # still reaches the goal
    lib = PrimitiveLibrary(3, threshold=0.05).fit([(t, y), ...])
    lib.parse(t_new, y_new).bounds                       # most likely segmentation
    hsmm = HiddenSemiMarkov().fit_labelled([x], [labels])   # phases with durations, (n, C) channels
    hsmm.predict(x_new)                                   # a label per sample
"""

from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.dmp import DMP
from thirdhand.primitives.hsmm import HiddenSemiMarkov
from thirdhand.primitives.primitive_library import Parse, PrimitiveLibrary
from thirdhand.primitives.promp import ProMP
from thirdhand.primitives.quaternion_dmp import PoseDMP, QuaternionDMP
from thirdhand.primitives.stage import primitives_stage

__all__ = [
    "DMP",
    "HiddenSemiMarkov",
    "Parse",
    "PoseDMP",
    "PrimitiveError",
    "PrimitiveLibrary",
    "ProMP",
    "QuaternionDMP",
    "primitives_stage",
]
