"""Online interaction phases: the CRF's forward filter and a fixed-lag smoother per pair.

For the binary chain of :mod:`thirdhand.segment.chain` with unary potentials
``(0, s_t)``, ``s_t = x_t · w`` and transition weights ``T[a, b]``, the forward
filter keeps ``α_t(a) = log p(y_t = a | x_1..t)`` (normalised):

``α_t(a) = s_t[a = 1] + logsumexp_b (T[a, b] + α_{t−1}(b)) − c_t``.

``p(y_t = 1 | x_1..t)`` is exactly the last marginal of the offline
forward–backward pass run on ``x_1..t`` (tested to 1e-9). The fixed-lag
smoother gives ``p(y_{t−L} | x_1..t)`` by a backward pass over the last ``L``
rows (tested against the offline marginals of ``x_1..t``). Each pair uses the
weights of its kind, from the same :class:`~thirdhand.segment.model.SegmentModel`
as offline; every update is vectorised over the pairs.

Latency of a label on the stream's clock: the feature lag
(:func:`thirdhand.live.features.feature_lag`, 0.20 s for the shipped model)
plus up to one latent step (0.05 s), plus ``L`` steps for the smoothed label
(default ``L = 4``: 0.20 s).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration

if TYPE_CHECKING:
    from thirdhand.live.features import FeatureRows
    from thirdhand.segment.model import SegmentModel


#: Default smoother lag, latent steps (0.20 s at the shipped model's 20 Hz).
SMOOTHER_LAG = 4


def _lse2(a: FloatArray, b: FloatArray) -> FloatArray:
    m = np.maximum(a, b)
    return np.asarray(m + np.log(np.exp(a - m) + np.exp(b - m)), dtype=np.float64)


class ChainFilter:
    """Forward filter and fixed-lag smoother of many binary chains at once.

    Parameters
    ----------
    weights : ndarray, shape (n_chains, n_features)
        State weights of each chain (its pair kind's ``coef_state``).
    trans : ndarray, shape (n_chains, 2, 2)
        ``trans[i, a, b]``: weight of ``y_t = a`` after ``y_{t−1} = b`` for chain ``i``.
    lag : int
        Smoother lag ``L``, steps (0: the smoothed values are the filtered ones).

    Attributes
    ----------
    log_alpha : ndarray, shape (n_chains, 2)
        Normalised ``log p(y_t | x_1..t)`` after the last update.
    n_steps : int
        Updates so far.
    """

    def __init__(self, weights: FloatArray, trans: FloatArray, lag: int = SMOOTHER_LAG) -> None:
        self.weights = np.ascontiguousarray(weights, np.float64)
        self.trans = np.ascontiguousarray(trans, np.float64)
        if self.weights.ndim != 2 or self.trans.shape != (self.weights.shape[0], 2, 2):
            raise ValueError(
                f"weights (n, d) and trans (n, 2, 2) expected, got {self.weights.shape} "
                f"and {self.trans.shape}"
            )
        if lag < 0:
            raise ValueError(f"smoother lag must be >= 0 steps, got {lag}")
        self.lag = int(lag)
        n = self.weights.shape[0]
        self.log_alpha = np.zeros((n, 2))
        self.n_steps = 0
        self._alphas: deque[FloatArray] = deque(maxlen=self.lag + 1)
        self._scores: deque[FloatArray] = deque(maxlen=self.lag + 1)

    def update(self, x: FloatArray) -> FloatArray:
        """Add the rows of one step; return ``p(y_t = 1 | x_1..t)``, shape (n_chains,).

        Parameters
        ----------
        x : ndarray, shape (n_chains, n_features)
        """
        s = np.einsum("ij,ij->i", np.asarray(x, np.float64), self.weights)
        if self.n_steps == 0:
            la = np.stack([np.zeros_like(s), s], axis=1)
        else:
            prev = self.log_alpha
            tr = self.trans
            la = np.stack(
                [
                    _lse2(tr[:, 0, 0] + prev[:, 0], tr[:, 0, 1] + prev[:, 1]),
                    s + _lse2(tr[:, 1, 0] + prev[:, 0], tr[:, 1, 1] + prev[:, 1]),
                ],
                axis=1,
            )
        la = la - _lse2(la[:, 0], la[:, 1])[:, None]
        self.log_alpha = la
        self.n_steps += 1
        self._alphas.append(la)
        self._scores.append(s)
        return np.asarray(np.exp(la[:, 1]), dtype=np.float64)

    def smoothed(self) -> tuple[int, FloatArray]:
        """``p(y_{t−L} = 1 | x_1..t)`` after the last update.

        Returns
        -------
        step : int
            The step ``t − L`` the values belong to (0-based; smaller lag near the start).
        prob : ndarray, shape (n_chains,)
        """
        k = len(self._alphas)
        if k == 0:
            raise ValueError("no step filtered yet")
        beta = np.zeros((self.weights.shape[0], 2))
        tr = self.trans
        for i in range(k - 1, 0, -1):
            s = self._scores[i]
            # beta_{t-1}(b) = lse_a (T[a, b] + u_t(a) + beta_t(a))
            b0 = _lse2(tr[:, 0, 0] + beta[:, 0], tr[:, 1, 0] + s + beta[:, 1])
            b1 = _lse2(tr[:, 0, 1] + beta[:, 0], tr[:, 1, 1] + s + beta[:, 1])
            beta = np.stack([b0, b1], axis=1)
        m = self._alphas[0] + beta
        m = m - _lse2(m[:, 0], m[:, 1])[:, None]
        return self.n_steps - k, np.asarray(np.exp(m[:, 1]), dtype=np.float64)


@dataclass(frozen=True)
class PhaseUpdate:
    """Interaction phases of every pair at one latent step.

    Attributes
    ----------
    step : int
        Latent step of the filtered values.
    time : float
        Its centre, seconds on the stream's clock.
    filtered : ndarray, shape (n_pairs,)
        ``p(y = 1 | rows so far)``; 0 where the rest gate applies, NaN inside a
        run without evidence longer than the model's ``max_gap_s``.
    smoothed_step : int
        Step of ``smoothed`` (``step − lag``).
    smoothed : ndarray, shape (n_pairs,)
        Fixed-lag smoothed probability of step ``smoothed_step`` (same gates).
    holding : dict (hand, object) -> bool
        Whether a hand moves an object at ``smoothed_step``: at least the model's
        ``min_fingers`` of its fingers' smoothed labels are 1.
    """

    step: int
    time: float
    filtered: FloatArray
    smoothed_step: int
    smoothed: FloatArray
    holding: dict[tuple[str, str], bool]


class OnlinePhases:
    """The segmentation CRF run causally on a stream: features, filter, smoother, hands.

    Parameters
    ----------
    bodies : sequence of BodyInfo
        The stream's bodies, in the order of its frames' rows.
    meta : mapping
        The stream's metadata (part boxes for the contact feature).
    model : SegmentModel, optional
        The offline model (default: the shipped one).
    lag : int
        Smoother lag, latent steps.
    pairs : sequence of (str, str), optional
        Default: :func:`thirdhand.segment.pipeline.default_pairs` of the bodies.
    """

    def __init__(
        self,
        bodies: Sequence[BodyInfo],
        meta: Mapping[str, Any],
        model: SegmentModel | None = None,
        *,
        lag: int = SMOOTHER_LAG,
        pairs: Sequence[tuple[str, str]] | None = None,
    ) -> None:
        from thirdhand.live.features import CausalFeatures
        from thirdhand.segment.hands import finger_groups
        from thirdhand.segment.model import default_model
        from thirdhand.segment.pipeline import HAND_KINDS, default_pairs, pair_kind

        self.model = default_model() if model is None else model
        skeleton = skeleton_demo(bodies, meta)
        self.names = skeleton.body_names
        self.pairs = list(default_pairs(skeleton) if pairs is None else pairs)
        self.kinds = [pair_kind(skeleton, a, b) for a, b in self.pairs]
        index = {n: i for i, n in enumerate(self.names)}
        ip = [(index[a], index[b]) for a, b in self.pairs]
        self.features = CausalFeatures(self.names, ip, self.model.features, meta)
        crfs = [self.model.crf(k) for k in self.kinds]
        self.filter = ChainFilter(
            np.stack([c.coef_state_ for c in crfs]),
            np.stack([c.coef_transition_ for c in crfs]),
            lag=lag,
        )
        self._gate = np.array([k in HAND_KINDS for k in self.kinds]) & self.model.rest_gate
        self._pa = np.array([a for a, _ in ip], dtype=np.int64)
        self._pb = np.array([b for _, b in ip], dtype=np.int64)
        self._max_gap = int(np.floor(self.model.max_gap_s * self.model.features.latent_rate + 1e-9))
        self._no_ev = np.zeros(len(self.pairs), dtype=np.int64)
        self._hist: deque[tuple[BoolArray, BoolArray]] = deque(maxlen=lag + 1)
        self.hand_pairs: dict[tuple[str, str], list[int]] = {}
        for hand, fingers in finger_groups(skeleton).items():
            for i, (a, b) in enumerate(self.pairs):
                if a in fingers:
                    self.hand_pairs.setdefault((hand, b), []).append(i)
        self.min_fingers = self.model.min_fingers
        #: Latent steps by which filtered values trail the stream (features).
        self.feature_lag = self.features.lag

    def push(
        self, t: float, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> list[PhaseUpdate]:
        """Add one frame; return the phase updates of the steps it completed."""
        return [self._update(r) for r in self.features.push(t, pos, quat, valid)]

    def flush(self) -> list[PhaseUpdate]:
        """At the end of the stream: the updates of the remaining steps."""
        return [self._update(r) for r in self.features.flush()]

    def _update(self, rows: FeatureRows) -> PhaseUpdate:
        prob = self.filter.update(rows.x)
        self._no_ev = np.where(rows.evidence, 0, self._no_ev + 1)
        blank = self._no_ev > self._max_gap
        still = self._gate & (rows.rest[self._pa] | rows.rest[self._pb])
        self._hist.append((still, blank))
        prob = np.where(still, 0.0, np.where(blank, np.nan, prob))
        s_step, sm = self.filter.smoothed()
        s_still, s_blank = self._hist[0]
        sm = np.where(s_still, 0.0, np.where(s_blank, np.nan, sm))
        label = np.nan_to_num(sm, nan=0.0) > 0.5
        holding = {}
        for key, idx in self.hand_pairs.items():
            need = max(1, min(self.min_fingers, len(idx)))
            holding[key] = int(label[idx].sum()) >= need
        return PhaseUpdate(rows.step, rows.time, prob, s_step, sm, holding)


def skeleton_demo(bodies: Sequence[BodyInfo], meta: Mapping[str, Any]) -> Demonstration:
    """A two-frame, never-tracked Demonstration of the bodies: their kinds for pair rules."""
    nan3 = np.full((2, 3), np.nan)
    nan4 = np.full((2, 4), np.nan)
    names = [b.name for b in bodies]
    return Demonstration(
        [0.0, 1.0],
        list(bodies),
        {n: nan3 for n in names},
        {n: nan4 for n in names},
        valid={n: np.zeros(2, dtype=bool) for n in names},
        meta=dict(meta),
    )


__all__ = ["SMOOTHER_LAG", "ChainFilter", "OnlinePhases", "PhaseUpdate", "skeleton_demo"]
