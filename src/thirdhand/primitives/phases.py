"""The second level of the parse: runs of one skill grouped into phases.

The library parses a stream into skills; consecutive segments of one skill are
one *run* (:meth:`~thirdhand.primitives.primitive_library.Parse.merged`: a wiping phase of
many circles is one run of the circle skill). The same skill can serve
different phases — moving freely towards a surface and away from it — which
differ in where the run takes the arm. A run is described by

- its skill (one-hot, times :data:`SKILL_WEIGHT` standard deviations, so that
  runs of different skills join only when their motion says so strongly), and
- its net displacement in every shape channel (end minus start), standardised
  over the training runs,

and the runs are grouped by weighted k-means (weight = the run's length, best of
10 k-means++ restarts) into ``n_phases`` phases, learned on training streams and
applied to new ones (nearest centre). Consecutive runs of one phase merge.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.primitives.checks import PrimitiveError
from thirdhand.primitives.primitive_library import Parse

#: Weight of the skill identity in a run's descriptor, in standard deviations.
SKILL_WEIGHT = 3.0


def run_descriptors(y: FloatArray, parse: Parse, n_skills: int) -> tuple[FloatArray, FloatArray]:
    """Descriptor (unstandardised) and length of every run of a merged parse.

    Parameters
    ----------
    y : ndarray, shape (n, dims)
        Shape channels of the parsed stream.
    parse : Parse
        Merged (:meth:`Parse.merged`) parse of it.
    n_skills : int

    Returns
    -------
    desc : ndarray, shape (runs, n_skills + dims)
        One-hot skill, then net displacement per shape channel.
    length : ndarray, shape (runs,)
        Samples.
    """
    b = parse.bounds
    onehot = np.eye(n_skills)[parse.labels]
    disp = y[b[1:]] - y[b[:-1]]
    return np.hstack([onehot, disp]), np.diff(b).astype(np.float64)


class PhaseGrouper:
    """Group runs of skills into ``n_phases`` phases (see the module docstring).

    Attributes
    ----------
    centres_ : ndarray, shape (n_phases, n_skills + dims)
        In standardised descriptor units.
    """

    def __init__(self, n_phases: int, *, n_skills: int, seed: int = 0) -> None:
        self.n_phases = n_phases
        self.n_skills = n_skills
        self.seed = seed

    def _z(self, desc: FloatArray) -> FloatArray:
        z = desc.copy()
        z[:, : self.n_skills] *= SKILL_WEIGHT
        z[:, self.n_skills :] = (desc[:, self.n_skills :] - self.mu_) / self.sd_
        return z

    def fit(self, descs: Sequence[FloatArray], lengths: Sequence[FloatArray]) -> PhaseGrouper:
        """Learn the phase centres from the runs of training streams."""
        from scipy.cluster.vq import kmeans2

        if self.n_phases < 1:
            raise PrimitiveError(f"phases: at least 1 phase, got {self.n_phases}")
        d = np.vstack(descs)
        w = np.concatenate(lengths)
        if d.shape[0] < self.n_phases:
            raise PrimitiveError(
                f"phases: {d.shape[0]} runs of skills in the training streams for "
                f"{self.n_phases} phases"
            )
        disp = d[:, self.n_skills :]
        self.mu_ = np.average(disp, axis=0, weights=w)
        sd = np.sqrt(np.average((disp - self.mu_) ** 2, axis=0, weights=w))
        self.sd_ = np.where(sd > 0, sd, 1.0)
        z = self._z(d)
        best: tuple[float, FloatArray] | None = None
        for r in range(10):
            cent, lab = kmeans2(z, self.n_phases, minit="++", seed=self.seed + r)
            # weighted refinement: a few Lloyd steps with run lengths as weights
            for _ in range(20):
                for k in range(self.n_phases):
                    m = lab == k
                    if m.any():
                        cent[k] = np.average(z[m], axis=0, weights=w[m])
                lab = np.argmin(((z[:, None] - cent[None]) ** 2).sum(-1), axis=1)
            cost = float(w @ ((z - cent[lab]) ** 2).sum(axis=1))
            if best is None or cost < best[0]:
                best = (cost, cent)
        assert best is not None
        self.centres_ = best[1]
        return self

    def predict(self, desc: FloatArray) -> IntArray:
        """Phase of every run, shape (runs,)."""
        z = self._z(desc)
        return np.argmin(((z[:, None] - self.centres_[None]) ** 2).sum(-1), axis=1).astype(np.int64)

    def group(self, y: FloatArray, parse: Parse) -> Parse:
        """The merged parse relabelled by phase, consecutive runs of one phase merged."""
        desc, _ = run_descriptors(y, parse, self.n_skills)
        return Parse(parse.bounds, self.predict(desc), parse.log_prob, parse.candidates).merged()
