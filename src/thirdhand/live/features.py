"""Causal feature rows of the segmentation CRF, one latent step at a time.

The offline features (:mod:`thirdhand.segment.design`) use windows *centred*
on each latent step: the row of step ``k`` needs the frames of steps up to
``k + w − 1 − w // 2`` for every window ``w`` of the model. The causal variant
computes exactly that row as soon as those steps are complete: the rows are the
offline rows **delayed by** ``lag = max_w (w − 1 − w // 2)`` latent steps (the
shipped model: windows 5, 10 and 2 steps at 20 Hz, lag 4 steps = 0.20 s), plus
the wait for the current step to end (up to one step, 0.05 s). The same kernels
compute them, on a buffer of the last ``max_w // 2 + lag + 1`` steps.

What cannot be causal is replaced, and only that:

- the noise floor of each body (``adaptive_eps`` and the rest gate) is the
  offline estimator (:func:`thirdhand.segment.noise.noise_floor`'s median of
  squared second differences) over the frames seen so far (the last
  ``floor_span_s``), refreshed once a second;
- static gap filling (``fill_gaps_s``) needs the samples after a gap: online, a
  gap stays a gap (no evidence), as for a model without it.

With a model using neither (``adaptive_eps=False``, ``fill_gaps_s=0``) the rows
equal the offline rows (tested).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.se3_compiled import relative_pose_rows
from thirdhand.segment.contact import Box, body_box
from thirdhand.segment.design import FeatureConfig
from thirdhand.segment.features import _block_stats, _merge_buckets
from thirdhand.segment.noise import CHI2_3_MEDIAN, FLOOR_MIN, REST_FACTOR, NoiseFloor


def feature_lag(config: FeatureConfig) -> int:
    """Latent steps by which the causal rows trail the stream: ``max_w (w − 1 − w // 2)``."""
    return max(w - 1 - w // 2 for w in config.windows)


@dataclass(frozen=True)
class FeatureRows:
    """The design rows of one latent step for every pair.

    Attributes
    ----------
    step : int
        Latent step index (0 at the stream's first frame).
    time : float
        Centre of the step, seconds on the stream's clock.
    x : ndarray, shape (n_pairs, n_features)
        Design rows (all zero where there is no evidence).
    evidence : ndarray of bool, shape (n_pairs,)
    rest : ndarray of bool, shape (n_bodies,)
        Bodies showing no motion beyond their noise floor at this step.
    """

    step: int
    time: float
    x: FloatArray
    evidence: BoolArray
    rest: BoolArray


class _FloorTracker:
    """Running noise floors of every body from squared second differences."""

    def __init__(self, n_bodies: int, cap: int) -> None:
        self.cap = cap
        self.sq_pos = np.zeros((n_bodies, cap))
        self.sq_rot = np.zeros((n_bodies, cap))
        self.n = np.zeros(n_bodies, dtype=np.int64)
        self.total = np.zeros(n_bodies, dtype=np.int64)
        self.prev: list[tuple[FloatArray, FloatArray, BoolArray]] = []
        self.floors = [NoiseFloor(float("nan"), float("nan"), 0) for _ in range(n_bodies)]
        #: Position and rotation floors per body, NaN while unknown, shape (n_bodies,).
        self.pos = np.full(n_bodies, np.nan)
        self.rot = np.full(n_bodies, np.nan)

    def push(self, pos: FloatArray, quat: FloatArray, valid: BoolArray) -> None:
        self.prev.append((pos, quat, valid))
        if len(self.prev) > 3:
            self.prev.pop(0)
        if len(self.prev) < 3:
            return
        (p0, q0, v0), (p1, q1, v1), (p2, q2, v2) = self.prev
        ok = v0 & v1 & v2
        if not ok.any():
            return
        idx = np.flatnonzero(ok)
        d2p = p2[idx] - 2.0 * p1[idx] + p0[idx]
        d2q = q2[idx] - 2.0 * q1[idx] + q0[idx]
        col = self.total[idx] % self.cap
        self.sq_pos[idx, col] = np.einsum("ij,ij->i", d2p, d2p)
        self.sq_rot[idx, col] = np.einsum("ij,ij->i", d2q, d2q)
        self.total[idx] += 1
        self.n[idx] = np.minimum(self.total[idx], self.cap)

    def refresh(self) -> None:
        for i, n in enumerate(self.n):
            if n == 0:
                continue
            fp = float(np.median(self.sq_pos[i, :n])) / (6.0 * CHI2_3_MEDIAN)
            fr = float(np.median(self.sq_rot[i, :n])) / (6.0 * CHI2_3_MEDIAN)
            self.floors[i] = NoiseFloor(
                pos=max(3.0 * fp, FLOOR_MIN), rot=max(3.0 * fr, FLOOR_MIN), n=int(self.total[i])
            )
            self.pos[i], self.rot[i] = self.floors[i].pos, self.floors[i].rot


class CausalFeatures:
    """Design rows of body pairs, computed causally from a stream of frames.

    Parameters
    ----------
    names : sequence of str
        Body names, in the order of the frames' rows.
    pairs : sequence of (int, int)
        Pairs as row indices into ``names``.
    config : FeatureConfig
        The segmentation model's features.
    meta : mapping
        The stream's metadata (``geometry`` gives part boxes for the contact feature).
    floor_span_s : float
        Seconds of the most recent samples the noise floors are estimated from.
    rate_hz : float
        Nominal frame rate, Hz: sizes the floor buffers.
    """

    def __init__(
        self,
        names: Sequence[str],
        pairs: Sequence[tuple[int, int]],
        config: FeatureConfig,
        meta: Mapping[str, Any],
        *,
        floor_span_s: float = 60.0,
        rate_hz: float = 120.0,
    ) -> None:
        self.names = list(names)
        self.pairs = list(pairs)
        self.config = config
        self.lag = feature_lag(config)
        self.back = max(w // 2 for w in config.windows)
        self.boxes = [body_box(meta, n) for n in self.names]
        self._pa = np.array([a for a, _ in self.pairs], dtype=np.int64)
        self._pb = np.array([b for _, b in self.pairs], dtype=np.int64)
        self._windows = np.array(config.windows, dtype=np.int64)
        corners, lohi = _box_arrays(self.boxes)
        self._corner_a, self._corner_b = corners[self._pa], corners[self._pb]
        self._box_a, self._box_b = lohi[self._pa], lohi[self._pb]
        self.t0: float | None = None
        self.next_row = 0
        self._floors = _FloorTracker(len(self.names), max(100, int(floor_span_s * rate_hz)))
        self._last_refresh = -np.inf
        self._t: list[float] = []
        self._k: list[int] = []
        self._pos: list[FloatArray] = []
        self._quat: list[FloatArray] = []
        self._valid: list[BoolArray] = []
        self._qprev = np.zeros((len(self.names), 4))
        self._qhave = np.zeros(len(self.names), dtype=bool)
        self._last_step = -1

    @property
    def n_features(self) -> int:
        """Columns of a design row."""
        return len(self.config.feature_names)

    def step_of(self, t: float) -> int:
        """Latent step of a stream time, seconds (as offline ``latent_axis``)."""
        assert self.t0 is not None
        return int(np.floor((t - self.t0) * self.config.latent_rate + 1e-9))

    def push(
        self, t: float, pos: FloatArray, quat: FloatArray, valid: BoolArray
    ) -> list[FeatureRows]:
        """Add one frame; return the rows that became computable (oldest first)."""
        if self.t0 is None:
            self.t0 = float(t)
        v = np.asarray(valid, dtype=bool)
        q = np.where(v[:, None], quat, 0.0)
        # Sign continuity per body, as continuous_quat_rows over the whole track.
        flip = v & self._qhave & (np.einsum("ij,ij->i", q, self._qprev) < 0.0)
        q = np.where(flip[:, None], -q, q)
        self._qprev = np.where(v[:, None], q, self._qprev)
        self._qhave |= v
        p = np.where(v[:, None], pos, 0.0)
        self._floors.push(p, q, v)
        k = self.step_of(t)
        self._t.append(float(t))
        self._k.append(k)
        self._pos.append(p)
        self._quat.append(q)
        self._valid.append(v)
        self._last_step = k
        # Steps before k are complete: rows up to k - 1 - lag are computable.
        return self._emit(k - 1 - self.lag, final=False)

    def flush(self) -> list[FeatureRows]:
        """At the end of the stream: the remaining rows, windows clipped at the end."""
        return self._emit(self._last_step, final=True)

    def _emit(self, upto: int, *, final: bool) -> list[FeatureRows]:
        out = []
        while self.next_row <= upto:
            out.append(self._row(self.next_row, final=final))
            self.next_row += 1
        if out:
            keep_from = self.next_row - self.back
            cut = 0
            while cut < len(self._k) and self._k[cut] < keep_from:
                cut += 1
            if cut:
                for buf in (self._t, self._k, self._pos, self._quat, self._valid):
                    del buf[:cut]
        return out

    def _row(self, j: int, *, final: bool) -> FeatureRows:
        assert self.t0 is not None
        cfg = self.config
        time = self.t0 + (j + 0.5) / cfg.latent_rate
        if time - self._last_refresh >= 1.0:
            self._floors.refresh()
            self._last_refresh = time
        lo = max(j - self.back, 0)
        hi = j + self.lag + 1
        if final:
            hi = min(hi, self._last_step + 1)
        ks = np.asarray(self._k, dtype=np.int64)
        sel = (ks >= lo) & (ks < hi)
        n_pairs, n_bodies = len(self.pairs), len(self.names)
        if not sel.any():
            return FeatureRows(
                j,
                time,
                np.zeros((n_pairs, self.n_features)),
                np.zeros(n_pairs, dtype=bool),
                np.zeros(n_bodies, dtype=bool),
            )
        i0, i1 = int(np.argmax(sel)), len(sel) - int(np.argmax(sel[::-1]))
        frame_step = ks[i0:i1] - lo
        n_local = hi - lo
        # (n, B, 3); frames are in step order. Contiguous float64/bool whatever the source
        # gave: the kernel is compiled for those before the stream (a new layout or dtype
        # would compile mid-stream, a stall of seconds)
        pos = np.ascontiguousarray(np.stack(self._pos[i0:i1]), dtype=np.float64)
        quat = np.ascontiguousarray(np.stack(self._quat[i0:i1]), dtype=np.float64)
        valid = np.ascontiguousarray(np.stack(self._valid[i0:i1]), dtype=np.bool_)
        r = j - lo
        per_step = np.bincount(frame_step, minlength=n_local).astype(float)
        w0 = cfg.window
        nominal = float(per_step[max(r - w0 // 2, 0) : min(r - w0 // 2 + w0, n_local)].sum())
        bv, pv, pmean = _window_rows(
            pos, quat, valid, frame_step, n_local, r, self._windows, self._pa, self._pb
        )
        return self._design(j, time, bv, pv, pmean, nominal)

    def _design(
        self,
        j: int,
        time: float,
        bv: FloatArray,
        pv: FloatArray,
        pmean: FloatArray,
        nominal: float,
    ) -> FeatureRows:
        """Design rows from the window statistics of :func:`_window_rows`."""
        cfg = self.config
        fp, fr = self._floors.pos, self._floors.rot
        # Rest (shortest window), as DemoFeatures.rest: unknown floor -> not at rest.
        with np.errstate(invalid="ignore"):
            rest = (
                (bv[0, :, 0] <= REST_FACTOR * fp)
                & (bv[0, :, 1] <= REST_FACTOR * fr)
                & (bv[0, :, 2] >= 2)
            )
        pa, pb = self._pa, self._pb
        count = pv[0, :, 2]
        evidence = (count >= cfg.min_valid_fraction * nominal) & (count >= 2)
        n_w = len(cfg.windows)
        raw = np.empty((len(pa), 4 * n_w))
        for w in range(n_w):
            raw[:, 4 * w] = bv[w, pa, 0] + bv[w, pb, 0]
            raw[:, 4 * w + 1] = bv[w, pa, 1] + bv[w, pb, 1]
            raw[:, 4 * w + 2] = pv[w, :, 0]
            raw[:, 4 * w + 3] = pv[w, :, 1]
        raw = np.maximum(raw, 0.0)
        if cfg.transform == "log":
            ep = np.full(len(pa), cfg.eps_pos)
            er = np.full(len(pa), cfg.eps_rot)
            if cfg.adaptive_eps:
                both = np.isfinite(fp[pa]) & np.isfinite(fp[pb])
                ep = np.where(both, np.maximum(ep, fp[pa] + fp[pb]), ep)
                er = np.where(both, np.maximum(er, fr[pa] + fr[pb]), er)
            e4 = np.stack([ep, er, ep, er], axis=1)
            feats = np.log(np.tile(e4, (1, n_w)) + raw)
        else:
            feats = raw
        cols = [np.ones((len(pa), 1)), feats]
        mean_pos, mean_quat, dist = pmean[:, :3], pmean[:, 3:7], pmean[:, 7]
        if cfg.distance:
            cols.append(np.log(cfg.eps_dist + np.maximum(dist, 0.0))[:, None])
        if cfg.contact:
            gap = _box_gaps(mean_pos, mean_quat, self._corner_a, self._corner_b,
                            self._box_a, self._box_b)  # fmt: skip
            gap = np.nan_to_num(np.maximum(gap, 0.0), nan=0.0)
            cols.append(np.log(cfg.eps_contact + gap)[:, None])
        x = np.concatenate(cols, axis=1)
        x[~evidence] = 0.0
        return FeatureRows(j, time, x, evidence, rest)


def _box_arrays(boxes: Sequence[Box | None]) -> tuple[FloatArray, FloatArray]:
    """Corners (n, 8, 3) and (lo, hi) stacked (n, 2, 3); no box: a point at the origin."""
    corners = np.zeros((len(boxes), 8, 3))
    lohi = np.zeros((len(boxes), 2, 3))
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=bool)
    for i, box in enumerate(boxes):
        if box is not None:
            corners[i] = np.where(idx, box[1], box[0])
            lohi[i] = box
    return corners, lohi


@numba.njit(cache=True, nogil=True)
def _box_gaps(  # pragma: no cover - compiled
    pos_ba: FloatArray,
    quat_ba: FloatArray,
    corner_a: FloatArray,
    corner_b: FloatArray,
    box_a: FloatArray,
    box_b: FloatArray,
) -> FloatArray:
    """:func:`thirdhand.segment.contact.box_gap` of many pairs at once, shape (n_pairs,).

    ``corner_*`` (n_pairs, 8, 3) and ``box_*`` (n_pairs, 2, 3) from :func:`_box_arrays`.
    """
    n = pos_ba.shape[0]
    out = np.full(n, np.nan)
    rot = np.empty((3, 3))
    for i in range(n):
        nq = np.sqrt(np.sum(quat_ba[i] ** 2))
        if not nq > 0.0 or not np.all(np.isfinite(pos_ba[i])):
            continue
        x, y, z, w = quat_ba[i, 0] / nq, quat_ba[i, 1] / nq, quat_ba[i, 2] / nq, quat_ba[i, 3] / nq
        rot[0, 0], rot[0, 1], rot[0, 2] = (
            1 - 2 * (y * y + z * z),
            2 * (x * y - z * w),
            2 * (x * z + y * w),
        )
        rot[1, 0], rot[1, 1], rot[1, 2] = (
            2 * (x * y + z * w),
            1 - 2 * (x * x + z * z),
            2 * (y * z - x * w),
        )
        rot[2, 0], rot[2, 1], rot[2, 2] = (
            2 * (x * z - y * w),
            2 * (y * z + x * w),
            1 - 2 * (x * x + y * y),
        )
        best = np.inf
        for c in range(8):
            # B's corner in A's frame against A's box; A's corner in B's frame against B's box.
            gb = 0.0
            ga = 0.0
            for k in range(3):
                pb = pos_ba[i, k]
                for m in range(3):
                    pb += rot[k, m] * corner_b[i, c, m]
                pa = 0.0
                for m in range(3):
                    pa += rot[m, k] * (corner_a[i, c, m] - pos_ba[i, m])
                e = max(max(box_a[i, 0, k] - pb, pb - box_a[i, 1, k]), 0.0)
                gb += e * e
                e = max(max(box_b[i, 0, k] - pa, pa - box_b[i, 1, k]), 0.0)
                ga += e * e
            best = min(best, np.sqrt(gb), np.sqrt(ga))
        out[i] = best
    return out


@numba.njit(cache=True, nogil=True)
def _window_moments(  # pragma: no cover - compiled
    cp: FloatArray,
    mp: FloatArray,
    sp: FloatArray,
    cq: FloatArray,
    mq: FloatArray,
    sq: FloatArray,
    lo: int,
    hi: int,
    mu3: FloatArray,
    mu4: FloatArray,
    out: FloatArray,
) -> float:
    """Merged moments of latent steps ``[lo, hi)``: ``out`` = (position variance,
    rotation variance, samples); the means are left in ``mu3`` and ``mu4``."""
    c, m = _merge_buckets(cp, mp, sp, lo, hi, mu3)
    _, mr = _merge_buckets(cq, mq, sq, lo, hi, mu4)
    if c > 0.0:
        out[0] = max(m / c, 0.0)
        out[1] = max(mr / c, 0.0)
    out[2] = c
    return float(c)


@numba.njit(cache=True, nogil=True)
def _window_rows(  # pragma: no cover - compiled
    pos: FloatArray,
    quat: FloatArray,
    valid: BoolArray,
    step: IntArray,
    n_steps: int,
    r: int,
    windows: IntArray,
    pa: IntArray,
    pb: IntArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Window statistics at local step ``r`` of every body and pair, with the offline kernels.

    Parameters
    ----------
    pos : ndarray, shape (n, n_bodies, 3); quat (n, n_bodies, 4) sign-continuous;
    valid : ndarray of bool, shape (n, n_bodies)
    step : ndarray of int, shape (n,)
        Local latent step of each frame, ``0 … n_steps − 1``.

    Returns
    -------
    body : ndarray, shape (n_windows, n_bodies, 3)
        Position variance, quaternion variance, valid count.
    pair : ndarray, shape (n_windows, n_pairs, 3)
        The same of B's pose in A's frame.
    pair_mean : ndarray, shape (n_pairs, 8)
        First window's mean relative position (3), quaternion (4) and distance.
    """
    n, n_b, _ = pos.shape
    n_w = windows.size
    body = np.zeros((n_w, n_b, 3))
    pair = np.zeros((n_w, pa.size, 3))
    pmean = np.zeros((pa.size, 8))
    mu3 = np.zeros(3)
    mu4 = np.zeros(4)
    mu1 = np.zeros(1)
    for b in range(n_b):
        v = valid[:, b].copy()
        if not v.any():
            continue
        p = pos[:, b, :].copy()
        q = quat[:, b, :].copy()
        cp, mp, sp = _block_stats(p, v, step, n_steps)
        cq, mq, sq = _block_stats(q, v, step, n_steps)
        for w in range(n_w):
            ww = windows[w]
            lo = max(r - ww // 2, 0)
            hi = min(r - ww // 2 + ww, n_steps)
            _window_moments(cp, mp, sp, cq, mq, sq, lo, hi, mu3, mu4, body[w, b])
    for i in range(pa.size):
        a = pa[i]
        b = pb[i]
        v = valid[:, a] & valid[:, b]
        if not v.any():
            continue
        dp, dq = relative_pose_rows(
            pos[:, a, :].copy(), quat[:, a, :].copy(), pos[:, b, :].copy(),
            quat[:, b, :].copy(), v,
        )  # fmt: skip
        dist = np.zeros((n, 1))
        for k in range(n):
            dist[k, 0] = np.sqrt(dp[k, 0] ** 2 + dp[k, 1] ** 2 + dp[k, 2] ** 2)
        cp, mp, sp = _block_stats(dp, v, step, n_steps)
        cq, mq, sq = _block_stats(dq, v, step, n_steps)
        cd, md, sd = _block_stats(dist, v, step, n_steps)
        for w in range(n_w):
            ww = windows[w]
            lo = max(r - ww // 2, 0)
            hi = min(r - ww // 2 + ww, n_steps)
            c = _window_moments(cp, mp, sp, cq, mq, sq, lo, hi, mu3, mu4, pair[w, i])
            if w == 0 and c > 0.0:
                _merge_buckets(cd, md, sd, lo, hi, mu1)
                for k in range(3):
                    pmean[i, k] = mu3[k]
                for k in range(4):
                    pmean[i, 3 + k] = mu4[k]
                pmean[i, 7] = mu1[0]
    return body, pair, pmean


__all__ = ["CausalFeatures", "FeatureRows", "feature_lag"]
