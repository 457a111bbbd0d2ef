"""From a demonstration and body pairs to the CRF's design matrices.

The design row of a latent step is ``[1, f(ν_π), f(ν_ρ), f(ζ_π), f(ζ_ρ)]``: a
bias, then the four core features of :mod:`thirdhand.segment.features` through
a monotone transform ``f``: ``log(ε + v)`` (the default, ``ε`` per unit:
``eps_pos`` m², ``eps_rot`` for quaternion variances) or ``v`` itself
(``transform="linear"``).

Optionally (``distance=True``) a last column ``log(eps_dist + d̄)``, ``d̄`` the
window-mean distance between the two bodies' origins. The four variances
describe motion; when both bodies are still they say nothing. With sensor noise
they still hint at the distance (one body's rotation noise times the lever arm
to the other shows in ``ζ_π``), so a model trained on noisy data learns "near
and still" vs "far and still" from it, and loses it on noise-free data: on the
synthetic scenes the distance column lifts held-out noise-free part–part frame
F1 from 0.66 to 0.89 (noisy 0.85 to 0.87, finger–object unchanged). The shipped
model uses it; the report's model is ``distance=False``.

Optionally (``long_window > 0``) the four core features again over a longer
centred window, appended after them. A short window (0.25 s) resolves screwing
strokes of half a second and the pauses between them; a part held in a hand
moves with it by only a few millimetres at 0.3–3 Hz, which a 0.25 s window
barely sees above 1 mm of sensor noise and a 0.5–1 s window does.

Optionally (``extra_windows``) the four core features over further centred
windows (latent steps), appended after the long-window ones.

Optionally (``contact=True``) a last column ``log(eps_contact + g)``, ``g`` the
gap between the two bodies' bounding boxes (:mod:`thirdhand.segment.contact`;
a body without a box is a point, so without geometry ``g`` is the distance
between the origins).

Optionally (``adaptive_eps=True``) the ``ε`` of the log transform of a pair is
raised to the pair's measured noise floor (:mod:`thirdhand.segment.noise`):
``ε = max(eps, τ_A + τ_B)``, so that on a noisy tracker (AR tags, 1–3 cm) the
noise of a still pair maps where a still pair of a precise tracker does; for
trackers of 1 mm or better the configured ``ε`` (3e-5 m²) is already above the
floor and nothing changes.

Steps without evidence (fewer valid samples in the window than
``min_valid_fraction`` of its nominal frame count) get an all-zero row: a zero
state potential for both labels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.se3_compiled import continuous_quat_rows
from thirdhand.segment.contact import body_box, box_gap
from thirdhand.segment.features import (
    RAW_FEATURE_NAMES,
    BodyStats,
    LatentAxis,
    SegmentationError,
    body_stats_multi,
    latent_axis,
    pair_stats_multi,
    raw_pair_features,
)
from thirdhand.segment.noise import NoiseFloor, at_rest, noise_floor
from thirdhand.segment.static_fill import fill_static_gaps


@dataclass(frozen=True)
class FeatureConfig:
    """How features are computed; stored with every model.

    Attributes
    ----------
    latent_rate : float
        Latent steps per second, Hz (the report: about 10).
    window : int
        Window length in latent steps, centred.
    transform : {"log", "linear"}
    eps_pos : float
        ``ε`` of the log transform for position variances, m². The default, about
        the variance of a still body seen with 1–2 mm of noise, maps every still
        body to about the same value whatever the sensor's noise floor (a Polhemus
        at rest shows ~1e-6 m², synthetic data ~1e-5 m²).
    eps_rot : float
        ``ε`` of the log transform for quaternion variances (same reasoning).
    min_valid_fraction : float
        Fraction of a window's frames that must be valid (both bodies) for evidence.
    distance : bool
        Append ``log(eps_dist + d̄)``, ``d̄`` the window mean of the distance between
        the two bodies' origins (m): an addition to the report's features, off by
        default (see the module docstring).
    eps_dist : float
        ``ε`` of the distance feature, metres.
    long_window : int
        When > 0, the four core features are also computed over this longer
        centred window (latent steps) and appended: the short window resolves
        brief strokes, the long one the small, slow co-motion of a part held in
        a hand (0: off, the report's four features only).
    extra_windows : tuple of int
        Further centred windows (latent steps) over which the four core features
        are computed and appended (empty: none).
    contact : bool
        Append ``log(eps_contact + g)``, ``g`` the bounding-box gap of the pair,
        metres (:mod:`thirdhand.segment.contact`; the origin distance without
        geometry).
    eps_contact : float
        ``ε`` of the contact feature, metres.
    adaptive_eps : bool
        Raise ``eps_pos`` / ``eps_rot`` of a pair to its measured noise floor
        (see the module docstring).
    fill_gaps_s : float
        Bridge tracking gaps of up to this many seconds across which a body
        stayed still (:mod:`thirdhand.segment.static_fill`); 0: off.
    """

    latent_rate: float = 10.0
    window: int = 5
    transform: str = "log"
    eps_pos: float = 1e-5
    eps_rot: float = 1e-4
    min_valid_fraction: float = 0.25
    distance: bool = False
    eps_dist: float = 0.02
    long_window: int = 0
    extra_windows: tuple[int, ...] = ()
    contact: bool = False
    eps_contact: float = 0.005
    adaptive_eps: bool = False
    fill_gaps_s: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "extra_windows", tuple(int(w) for w in self.extra_windows))
        if any(w < 1 for w in self.extra_windows):
            raise SegmentationError(
                f"extra windows must be >= 1 latent step, got {list(self.extra_windows)}"
            )
        if self.transform not in ("log", "linear"):
            raise SegmentationError(f"transform must be 'log' or 'linear', got {self.transform!r}")
        if self.window < 1 or not self.latent_rate > 0:
            raise SegmentationError(
                f"need window >= 1 latent step and latent_rate > 0 Hz, got "
                f"{self.window} and {self.latent_rate}"
            )
        if self.long_window < 0:
            raise SegmentationError(f"long_window must be >= 0 steps, got {self.long_window}")
        if not (np.isfinite(self.fill_gaps_s) and self.fill_gaps_s >= 0):
            raise SegmentationError(f"fill_gaps_s must be >= 0 s, got {self.fill_gaps_s}")

    @property
    def feature_names(self) -> list[str]:
        """Names of the design columns."""
        wrap = "log_eps_{}" if self.transform == "log" else "{}"
        extra = ["log_eps_distance"] if self.distance else []
        extra += ["log_eps_contact"] if self.contact else []
        long = [wrap.format(f"long_{n}") for n in RAW_FEATURE_NAMES] if self.long_window else []
        long += [wrap.format(f"w{w}_{n}") for w in self.extra_windows for n in RAW_FEATURE_NAMES]
        return ["bias", *(wrap.format(n) for n in RAW_FEATURE_NAMES), *long, *extra]

    @property
    def windows(self) -> tuple[int, ...]:
        """The window lengths used, latent steps: ``window``, ``long_window``, ``extra_windows``."""
        long = (self.long_window,) if self.long_window else ()
        return (self.window, *long, *self.extra_windows)

    def to_dict(self) -> dict[str, object]:
        """JSON-able form."""
        return asdict(self)


def design_matrix(
    raw: FloatArray,
    evidence: BoolArray,
    config: FeatureConfig,
    distance: FloatArray | None = None,
    contact: FloatArray | None = None,
    *,
    eps: tuple[float, float] | None = None,
) -> FloatArray:
    """Design rows from raw features.

    Parameters
    ----------
    raw : ndarray, shape (n_steps, 4 × len(config.windows))
        Columns ``ν_π`` (m²), ``ν_ρ``, ``ζ_π`` (m²), ``ζ_ρ``; then the same over
        each further window of ``config.windows``.
    evidence : ndarray of bool, shape (n_steps,)
    config : FeatureConfig
    distance : ndarray, shape (n_steps,), metres, optional
        Window mean distance between the bodies; required when ``config.distance``.
    contact : ndarray, shape (n_steps,), metres, optional
        Bounding-box gap of the bodies; required when ``config.contact``.
    eps : (float, float), optional
        ``ε`` of the log transform for positions (m²) and rotations, instead of
        the configuration's.

    Returns
    -------
    ndarray, shape (n_steps, len(config.feature_names))
    """
    raw = np.maximum(np.asarray(raw, dtype=np.float64), 0.0)
    if config.transform == "log":
        ep, er = (config.eps_pos, config.eps_rot) if eps is None else eps
        e4 = np.array([ep, er, ep, er])
        feats = np.log(np.tile(e4, raw.shape[1] // 4) + raw)
    else:
        feats = raw
    cols = [np.ones((raw.shape[0], 1)), feats]
    if config.distance:
        if distance is None:
            raise SegmentationError("this feature configuration needs the pair distance")
        cols.append(np.log(config.eps_dist + np.maximum(distance, 0.0))[:, None])
    if config.contact:
        if contact is None:
            raise SegmentationError("this feature configuration needs the contact distance")
        gap = np.nan_to_num(np.maximum(contact, 0.0), nan=0.0)
        cols.append(np.log(config.eps_contact + gap)[:, None])
    x = np.concatenate(cols, axis=1)
    x[~np.asarray(evidence, dtype=bool)] = 0.0
    return x


class DemoFeatures:
    """Feature extraction for many pairs of one demonstration, sharing per-body work.

    Parameters
    ----------
    demo : Demonstration
    config : FeatureConfig

    Attributes
    ----------
    axis : LatentAxis
    gaps : dict (a, b) -> ndarray, shape (n_steps,), metres
        Bounding-box gap of every pair computed so far whose two bodies both have
        a box (:mod:`thirdhand.segment.contact`), for the assembly closure.
    """

    def __init__(self, demo: Demonstration, config: FeatureConfig) -> None:
        self.demo = demo
        self.config = config
        self.axis: LatentAxis = latent_axis(demo.t, config.latent_rate)
        self.gaps: dict[tuple[str, str], FloatArray] = {}
        self._bodies: dict[str, list[BodyStats]] = {}
        self._floors: dict[str, NoiseFloor] = {}
        #: Frames filled per body by :mod:`thirdhand.segment.static_fill`.
        self.filled: dict[str, int] = {}
        self._tracks: dict[str, tuple[FloatArray, FloatArray, BoolArray]] = {}
        per_step = np.bincount(self.axis.frame_step, minlength=self.axis.n_steps).astype(float)
        half = config.window // 2
        cs = np.concatenate([[0.0], np.cumsum(per_step)])
        k = np.arange(self.axis.n_steps)
        lo = np.clip(k - half, 0, self.axis.n_steps)
        hi = np.clip(k - half + config.window, 0, self.axis.n_steps)
        #: Frames per window whatever their validity, shape (n_steps,).
        self.nominal: FloatArray = cs[hi] - cs[lo]

    def body_track(self, name: str) -> tuple[FloatArray, FloatArray, BoolArray]:
        """A body's positions, quaternions and validity on the recording's frames, with
        short gaps filled when ``fill_gaps_s`` is set (computed once)."""
        if name not in self._tracks:
            tr = self.demo.track(name)
            track = (tr.pos, tr.quat, tr.valid)
            if self.config.fill_gaps_s > 0:
                floor = noise_floor(*track)
                self._floors[name] = floor
                q = continuous_quat_rows(
                    np.where(tr.valid[:, None], tr.quat, 0.0).astype(np.float64), tr.valid
                )
                p, q, v, n = fill_static_gaps(
                    self.demo.t, tr.pos, q, tr.valid, floor, max_gap_s=self.config.fill_gaps_s
                )
                self.filled[name] = n
                track = (p, q, v)
            self._tracks[name] = track
        return self._tracks[name]

    def body(self, name: str) -> list[BodyStats]:
        """Windowed variances of one body (cached), one per window of the config."""
        if name not in self._bodies:
            p, q, v = self.body_track(name)
            self._bodies[name] = body_stats_multi(p, q, v, self.axis, self.config.windows)
        return self._bodies[name]

    def floor(self, name: str) -> NoiseFloor:
        """Noise floor of one body's track (cached; :mod:`thirdhand.segment.noise`)."""
        if name not in self._floors:
            self._floors[name] = noise_floor(*self.body_track(name))
        return self._floors[name]

    def rest(self, name: str) -> BoolArray:
        """Steps (n_steps,) at which the body shows no motion beyond its noise floor.

        Decided on the shortest window of the configuration; steps without any
        valid sample of the body are not at rest (nothing is known).
        """
        st = self.body(name)[0]
        return at_rest(st.var_pos, st.var_rot, self.floor(name)) & (st.count >= 2)

    def pair(self, a: str, b: str) -> tuple[FloatArray, BoolArray]:
        """Design matrix (n_steps, n_features) and evidence mask (n_steps,) of the pair (a, b)."""
        if a == b:
            raise SegmentationError(f"pair ({a!r}, {b!r}) pairs a body with itself")
        stats = pair_stats_multi(
            self.body_track(a),
            self.body_track(b),
            self.axis,
            self.config.windows,
            distance=self.config.distance,
        )
        sab = stats[0]
        raw = np.concatenate(
            [
                raw_pair_features(ba, bb, s)
                for ba, bb, s in zip(self.body(a), self.body(b), stats, strict=True)
            ],
            axis=1,
        )
        evidence = (sab.count >= self.config.min_valid_fraction * self.nominal) & (sab.count >= 2)
        gap = None
        meta = self.demo.meta
        box_a, box_b = body_box(meta, a), body_box(meta, b)
        if self.config.contact or (box_a is not None and box_b is not None):
            assert sab.mean_pos is not None and sab.mean_quat is not None
            gap = box_gap(sab.mean_pos, sab.mean_quat, box_a, box_b)
            if box_a is not None and box_b is not None:
                self.gaps[(a, b)] = gap
        eps = None
        if self.config.adaptive_eps:
            fa, fb = self.floor(a), self.floor(b)
            if fa.n and fb.n:
                eps = (
                    max(self.config.eps_pos, fa.pos + fb.pos),
                    max(self.config.eps_rot, fa.rot + fb.rot),
                )
        return design_matrix(raw, evidence, self.config, sab.distance, gap, eps=eps), evidence


def pair_design(
    demo: Demonstration, pairs: Sequence[tuple[str, str]], config: FeatureConfig
) -> tuple[LatentAxis, list[FloatArray], list[BoolArray]]:
    """Design matrices of several pairs of one demonstration.

    Returns
    -------
    axis : LatentAxis
    xs : list of ndarray, each of shape (n_steps, len(config.feature_names))
    evidence : list of ndarray of bool, each of shape (n_steps,)
    """
    feats = DemoFeatures(demo, config)
    xs, ev = [], []
    for a, b in pairs:
        x, e = feats.pair(a, b)
        xs.append(x)
        ev.append(e)
    return feats.axis, xs, ev


__all__ = ["DemoFeatures", "FeatureConfig", "design_matrix", "pair_design"]
