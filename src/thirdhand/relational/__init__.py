"""Relational inverse reinforcement learning (Munzer et al., IJCAI 2015).

Relational MDPs whose states are sets of ground atoms (:mod:`.logic`,
:mod:`.mdp`), their domains (:mod:`.domains`), relational trees (:mod:`.tilde`),
the boosted large-margin classifier BLMRIL (:mod:`.boosting`), cascaded
supervised IRL with relational trees, RCSI (:mod:`.csi`), reward shaping by
CMA-ES (:mod:`.shaping`), bagged reward trees (:mod:`.bagging`), the choice of
a learned reward by the demonstrations (:mod:`.selection`) and the perf
measure (:mod:`.evaluate`).
"""

from thirdhand.relational.logic import Atom, RelationalError, parse_atom

__all__ = ["Atom", "RelationalError", "parse_atom"]
