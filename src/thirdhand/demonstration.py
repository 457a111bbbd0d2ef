"""The Demonstration: one recording of a person assembling something.

A shared, strictly increasing time axis and, per tracked body, positions,
unit quaternions and a validity mask; body metadata; optional ground-truth
labels. Validated on construction, so every later stage can trust its input.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray
from thirdhand.errors import DemonstrationError

BodyKind = Literal["part", "tool", "finger", "hand", "head", "other"]
BODY_KINDS: tuple[str, ...] = ("part", "tool", "finger", "hand", "head", "other")
HandSide = Literal["left", "right", "other"]
HAND_SIDES: tuple[str, ...] = ("left", "right", "other")
CONSTRAINT_TYPES: tuple[str, ...] = (
    "fixed",
    "prismatic",
    "revolute",
    "free",
    "cylindrical",
    "screw",
)
#: The six degrees of freedom of a constraint, in the order of every (6, 2) range array.
DOF_NAMES: tuple[str, str, str, str, str, str] = ("tx", "ty", "tz", "rx", "ry", "rz")

#: Largest plausible coordinate of a motion-capture volume, metres. Beyond it the
#: data are almost surely millimetres read as metres.
MAX_PLAUSIBLE_POSITION_M = 50.0
#: Largest deviation from 1 of a stored quaternion's norm a reader accepts (and
#: renormalises); beyond it a cell is corrupt, not rounded.
MAX_QUAT_NORM_ERROR = 0.01


@dataclass(frozen=True)
class BodyInfo:
    """Metadata of one tracked body.

    Attributes
    ----------
    name : str
        Unique name, e.g. ``"seating"``, ``"/human/rh/thumb"``.
    kind : {"part", "tool", "finger", "hand", "head", "other"}
    hand : {"left", "right", "other"} or None
        For fingers and hands: which hand.
    hand_body : str or None
        For fingers: the name of the hand they belong to (a body or just a label
        such as ``"p1/right"``); fingers sharing it are aggregated together.
    person : str or None
        Who the body belongs to, for scenes with several people.
    oriented : bool
        False for a position-only track (a single marker, a position-only log):
        its quaternions are the identity wherever valid and carry no information.
    """

    name: str
    kind: BodyKind = "part"
    hand: HandSide | None = None
    hand_body: str | None = None
    person: str | None = None
    oriented: bool = True

    def __post_init__(self) -> None:
        if not self.name:
            raise DemonstrationError("body with an empty name")
        if self.kind not in BODY_KINDS:
            raise DemonstrationError(
                f"body {self.name!r}: kind must be one of {', '.join(BODY_KINDS)}, "
                f"got {self.kind!r}"
            )
        if self.hand is not None and self.hand not in HAND_SIDES:
            raise DemonstrationError(
                f"body {self.name!r}: hand must be one of {', '.join(HAND_SIDES)}, "
                f"got {self.hand!r}"
            )


#: A locked DOF's range.
_LOCKED: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class FreeDofs:
    """Ranges of the six degrees of freedom in a constraint frame; ``(0, 0)`` = locked.

    The one free-DOF value of the package: ground-truth labels
    (:class:`ConstraintEvent`), detection
    (:class:`~thirdhand.constraints.detect_types.ConstraintInstance`), the task
    file (:class:`thirdhand.task.Constraint`), the review GUI and execution all
    hold one. Immutable; change one range with
    ``dataclasses.replace(fd, rz=(lo, hi))``.

    Attributes
    ----------
    tx, ty, tz : tuple of 2 floats
        ``(min, max)`` translation along x, y, z of the constraint frame, metres.
    rx, ry, rz : tuple of 2 floats
        ``(min, max)`` rotation about x, y, z of the constraint frame, radians.

    Raises
    ------
    ValueError
        If a range is not two finite numbers with min <= max.

    Notes
    -----
    In a task file it is the object ``{"rx": [-3.14, 3.14], ...}`` (omitted DOFs
    locked). Unlike the task file's other objects, unknown keys are an error here
    (the ``__pydantic_config__`` below): a misspelt DOF name (``"Tx"``) silently
    read as locked would change what the robot may do. A plain dataclass rather
    than a pydantic model so that reading a recording does not import pydantic.
    """

    __pydantic_config__ = {"extra": "forbid", "allow_inf_nan": False}  # noqa: RUF012

    tx: tuple[float, float] = _LOCKED
    ty: tuple[float, float] = _LOCKED
    tz: tuple[float, float] = _LOCKED
    rx: tuple[float, float] = _LOCKED
    ry: tuple[float, float] = _LOCKED
    rz: tuple[float, float] = _LOCKED

    def __post_init__(self) -> None:
        for name in DOF_NAMES:
            r = getattr(self, name)
            try:
                lo, hi = (float(v) for v in r)
            except (TypeError, ValueError):
                raise ValueError(
                    f"DOF {name}: expected a range (min, max) of two numbers, got {r!r}"
                ) from None
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise ValueError(f"DOF {name}: range [{lo}, {hi}] is not finite")
            if not lo <= hi:
                raise ValueError(f"DOF {name}: range [{lo}, {hi}] has min > max")
            object.__setattr__(self, name, (lo, hi))

    @classmethod
    def from_array(cls, ranges: ArrayLike) -> FreeDofs:
        """Build from ``ranges``, array_like shape (6, 2): rows tx ty tz (m) rx ry rz (rad)."""
        arr = np.asarray(ranges, dtype=np.float64)
        if arr.shape != (6, 2):
            raise ValueError(f"expected DOF ranges of shape (6, 2), got {arr.shape}")
        return cls(*((float(lo), float(hi)) for lo, hi in arr))

    def __getitem__(self, dof: str) -> tuple[float, float]:
        """The range of one DOF by name: ``fd["rx"]`` (radians; metres for ``t*``).

        Raises
        ------
        KeyError
            If ``dof`` is not one of :data:`DOF_NAMES`.
        """
        if dof not in DOF_NAMES:
            raise KeyError(f"unknown DOF {dof!r} (expected one of {', '.join(DOF_NAMES)})")
        r: tuple[float, float] = getattr(self, dof)
        return r

    def ranges(self) -> list[tuple[float, float]]:
        """The six ranges in :data:`DOF_NAMES` order."""
        return [self[n] for n in DOF_NAMES]

    def array(self) -> FloatArray:
        """The ranges as an array, shape (6, 2): rows tx ty tz (m) rx ry rz (rad)."""
        return np.asarray(self.ranges(), dtype=np.float64)

    def free(self) -> list[str]:
        """Names of the DOFs whose range has width (min < max), in :data:`DOF_NAMES` order."""
        return [n for n in DOF_NAMES if self[n][0] != self[n][1]]


@dataclass(frozen=True)
class InteractionInterval:
    """Ground truth: bodies ``a`` and ``b`` interact over ``[start, end]`` seconds."""

    a: str
    b: str
    start: float
    end: float


@dataclass(frozen=True)
class ConstraintEvent:
    """Ground truth: a kinematic constraint between two parts appears (or is removed).

    Attributes
    ----------
    time : float
        Seconds on the demonstration's time axis.
    parent, child : str
        Body names; the pose is the child's in the parent's frame.
    type : str
        One of ``fixed, prismatic, revolute, free, cylindrical, screw``.
    pos : tuple of 3 floats
        Child origin in the parent frame, metres, at the moment the constraint is made.
    quat : tuple of 4 floats
        Child orientation in the parent frame, x y z w.
    free_dofs : FreeDofs
        Range of tx, ty, tz (metres) and rx, ry, rz (radians) in the constraint
        frame (the child's frame at the constraint pose); ``(0, 0)`` is a locked DOF.
        Six ``(min, max)`` pairs are accepted too and converted.
    symbol : str or None
        The constraint's symbol (e.g. a slot ``"c2"``), when known.
    removed : bool
        True for the event that removes the constraint.
    """

    time: float
    parent: str
    child: str
    type: str
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    free_dofs: FreeDofs = FreeDofs()
    symbol: str | None = None
    removed: bool = False

    def __post_init__(self) -> None:
        if self.type not in CONSTRAINT_TYPES:
            raise DemonstrationError(
                f"constraint {self.parent}->{self.child}: type must be one of "
                f"{', '.join(CONSTRAINT_TYPES)}, got {self.type!r}"
            )
        if len(self.pos) != 3 or len(self.quat) != 4:
            raise DemonstrationError(
                f"constraint {self.parent}->{self.child}: expected pos of 3 and quat of 4, "
                f"got {len(self.pos)}, {len(self.quat)}"
            )
        if not isinstance(self.free_dofs, FreeDofs):
            try:
                fd = FreeDofs.from_array(self.free_dofs)
            except ValueError as exc:
                raise DemonstrationError(
                    f"constraint {self.parent}->{self.child}: free DOFs: {exc}"
                ) from None
            object.__setattr__(self, "free_dofs", fd)

    @property
    def free_dof_array(self) -> FloatArray:
        """Free-DOF ranges as an array, shape (6, 2)."""
        return self.free_dofs.array()


@dataclass(frozen=True)
class PlanStep:
    """Ground truth: one step ``action(parent, child, symbol)`` of the assembly plan."""

    parent: str
    child: str
    symbol: str | None = None
    time: float | None = None


@dataclass(frozen=True)
class Labels:
    """Optional ground-truth labels of a demonstration."""

    interactions: tuple[InteractionInterval, ...] = ()
    constraints: tuple[ConstraintEvent, ...] = ()
    plan: tuple[PlanStep, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.interactions or self.constraints or self.plan)

    def bodies(self) -> set[str]:
        """Every body name the labels refer to."""
        names: set[str] = set()
        for i in self.interactions:
            names.update((i.a, i.b))
        for c in self.constraints:
            names.update((c.parent, c.child))
        for s in self.plan:
            names.update((s.parent, s.child))
        return names

    def interaction_pairs(self) -> list[tuple[str, str]]:
        """Distinct labelled pairs, in order of first appearance."""
        seen: dict[tuple[str, str], None] = {}
        for i in self.interactions:
            seen.setdefault((i.a, i.b), None)
        return list(seen)


@dataclass
class BodyTrack:
    """Arrays of one body. ``pos`` and ``quat`` are NaN where ``valid`` is False.

    Attributes
    ----------
    info : BodyInfo
    pos : ndarray, shape (n_frames, 3), metres, world frame
    quat : ndarray, shape (n_frames, 4), x y z w, world frame
    valid : ndarray of bool, shape (n_frames,)
    """

    info: BodyInfo
    pos: FloatArray
    quat: FloatArray
    valid: BoolArray


class Demonstration:
    """One recording: a shared time axis and the poses of every tracked body.

    Parameters
    ----------
    t : array_like, shape (n_frames,)
        Strictly increasing time stamps, seconds.
    bodies : sequence of BodyInfo
        One entry per tracked body; names must be unique.
    pos : mapping name -> array_like, shape (n_frames, 3)
        Positions in metres, world frame. NaN where the body was not tracked.
    quat : mapping name -> array_like, shape (n_frames, 4)
        Orientations, x y z w. Normalised on construction.
    valid : mapping name -> array_like of bool, shape (n_frames,), optional
        Frames where tracking was present. Defaults to frames where every
        coordinate is finite. Invalid frames are stored as NaN.
    labels : Labels, optional
        Ground-truth labels; every body they name must exist.
    meta : mapping, optional
        Free-form metadata (source file, up axis, original units...); JSON-able values.

    Raises
    ------
    DemonstrationError
        Naming the body, the frame and the problem.
    """

    def __init__(
        self,
        t: ArrayLike,
        bodies: Sequence[BodyInfo],
        pos: Mapping[str, ArrayLike],
        quat: Mapping[str, ArrayLike],
        valid: Mapping[str, ArrayLike] | None = None,
        *,
        labels: Labels | None = None,
        meta: Mapping[str, Any] | None = None,
    ) -> None:
        self.t: FloatArray = _check_time(t)
        n = self.t.size
        self.labels = labels if labels is not None else Labels()
        self.meta: dict[str, Any] = dict(meta or {})
        self._tracks: dict[str, BodyTrack] = {}
        for info in bodies:
            if info.name in self._tracks:
                raise DemonstrationError(f"body {info.name!r} appears twice")
            if info.name not in pos or info.name not in quat:
                raise DemonstrationError(f"body {info.name!r}: missing position or orientation")
            v = None if valid is None or info.name not in valid else valid[info.name]
            self._tracks[info.name] = _check_track(info, n, pos[info.name], quat[info.name], v)
        unknown = self.labels.bodies() - set(self._tracks)
        if unknown:
            raise DemonstrationError(
                f"labels name unknown bod{'y' if len(unknown) == 1 else 'ies'}: "
                f"{', '.join(sorted(unknown))}"
            )
        _check_labels(self.labels, self.t)

    # ------------------------------------------------------------------ access
    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.t.size)

    @property
    def body_names(self) -> list[str]:
        """Body names in order."""
        return list(self._tracks)

    @property
    def bodies(self) -> list[BodyInfo]:
        """Body metadata in order."""
        return [tr.info for tr in self._tracks.values()]

    @property
    def duration(self) -> float:
        """Time from first to last frame, seconds."""
        return float(self.t[-1] - self.t[0]) if self.t.size else 0.0

    @property
    def rate(self) -> float:
        """Nominal frame rate, Hz: the inverse of the median frame interval."""
        if self.t.size < 2:
            return float("nan")
        return float(1.0 / np.median(np.diff(self.t)))

    def __contains__(self, name: object) -> bool:
        return name in self._tracks

    def __len__(self) -> int:
        return len(self._tracks)

    def __repr__(self) -> str:
        return (
            f"Demonstration({len(self)} bodies, {self.n_frames} frames, "
            f"{self.duration:.2f} s, {self.rate:.1f} Hz)"
        )

    def track(self, name: str) -> BodyTrack:
        """Arrays of one body (read-only views)."""
        try:
            return self._tracks[name]
        except KeyError:
            raise DemonstrationError(
                f"no body named {name!r}; bodies are {', '.join(self._tracks)}"
            ) from None

    def info(self, name: str) -> BodyInfo:
        """Metadata of one body."""
        return self.track(name).info

    def pos(self, name: str) -> FloatArray:
        """Positions of one body, shape (n_frames, 3), metres, world frame; NaN where invalid."""
        return self.track(name).pos

    def quat(self, name: str) -> FloatArray:
        """Orientations of one body, shape (n_frames, 4), x y z w; NaN where invalid."""
        return self.track(name).quat

    def valid(self, name: str) -> BoolArray:
        """Tracking mask of one body, shape (n_frames,)."""
        return self.track(name).valid

    def missing_fraction(self, name: str) -> float:
        """Fraction of frames where the body was not tracked."""
        v = self.valid(name)
        return float(1.0 - v.mean()) if v.size else 0.0

    def bodies_of_kind(self, *kinds: str) -> list[str]:
        """Names of the bodies whose kind is one of ``kinds``."""
        return [n for n, tr in self._tracks.items() if tr.info.kind in kinds]

    def stacked(
        self, names: Sequence[str] | None = None
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """All poses as arrays.

        Returns
        -------
        pos : ndarray, shape (n_bodies, n_frames, 3)
        quat : ndarray, shape (n_bodies, n_frames, 4)
        valid : ndarray of bool, shape (n_bodies, n_frames)
        """
        names = self.body_names if names is None else list(names)
        tracks = [self.track(n) for n in names]
        if not tracks:
            n = self.n_frames
            return np.zeros((0, n, 3)), np.zeros((0, n, 4)), np.zeros((0, n), bool)
        return (
            np.stack([tr.pos for tr in tracks]),
            np.stack([tr.quat for tr in tracks]),
            np.stack([tr.valid for tr in tracks]),
        )

    # ------------------------------------------------------------ derivations
    def replace(
        self,
        *,
        t: ArrayLike | None = None,
        tracks: Mapping[str, tuple[ArrayLike, ArrayLike, ArrayLike]] | None = None,
        bodies: Sequence[BodyInfo] | None = None,
        labels: Labels | None = None,
        meta: Mapping[str, Any] | None = None,
    ) -> Demonstration:
        """A new demonstration with some parts replaced (the others are shared)."""
        bodies = self.bodies if bodies is None else list(bodies)
        src: Mapping[str, tuple[ArrayLike, ArrayLike, ArrayLike]] = (
            {n: (tr.pos, tr.quat, tr.valid) for n, tr in self._tracks.items()}
            if tracks is None
            else tracks
        )
        return Demonstration(
            self.t if t is None else t,
            bodies,
            {b.name: src[b.name][0] for b in bodies},
            {b.name: src[b.name][1] for b in bodies},
            {b.name: src[b.name][2] for b in bodies},
            labels=self.labels if labels is None else labels,
            meta=self.meta if meta is None else meta,
        )

    def select(self, names: Iterable[str]) -> Demonstration:
        """Keep only some bodies (in the given order); labels about others are dropped."""
        keep = list(names)
        for n in keep:
            self.track(n)
        ks = set(keep)
        lab = Labels(
            interactions=tuple(i for i in self.labels.interactions if {i.a, i.b} <= ks),
            constraints=tuple(c for c in self.labels.constraints if {c.parent, c.child} <= ks),
            plan=tuple(s for s in self.labels.plan if {s.parent, s.child} <= ks),
        )
        return self.replace(bodies=[self.info(n) for n in keep], labels=lab)

    def slice(self, start: float | None = None, end: float | None = None) -> Demonstration:
        """Frames with ``start <= t <= end`` seconds. Labels are clipped to the window."""
        lo = -np.inf if start is None else start
        hi = np.inf if end is None else end
        m = (self.t >= lo) & (self.t <= hi)
        if not np.any(m):
            raise DemonstrationError(
                f"slice [{start}, {end}] s holds no frame of [{self.t[0]:.6g}, {self.t[-1]:.6g}] s"
            )
        tracks = {n: (tr.pos[m], tr.quat[m], tr.valid[m]) for n, tr in self._tracks.items()}
        lab = clip_labels(self.labels, float(self.t[m][0]), float(self.t[m][-1]))
        return self.replace(t=self.t[m], tracks=tracks, labels=lab)

    def relative_pose(self, a: str, b: str) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Pose of body ``b`` in body ``a``'s frame over time.

        Returns
        -------
        pos : ndarray, shape (n_frames, 3), metres, a's frame
        quat : ndarray, shape (n_frames, 4), x y z w, sign-continuous
        valid : ndarray of bool, shape (n_frames,): both bodies tracked
        """
        ta, tb = self.track(a), self.track(b)
        valid = ta.valid & tb.valid
        p, q = se3.relative_pose(ta.pos, ta.quat, tb.pos, tb.quat)
        p[~valid] = np.nan
        q[~valid] = np.nan
        return p, se3.quat_make_continuous(q, valid), valid

    def with_continuous_quaternions(self) -> Demonstration:
        """Flip quaternion signs so consecutive valid samples have a positive dot product."""
        tracks = {
            n: (tr.pos, se3.quat_make_continuous(tr.quat, tr.valid), tr.valid)
            for n, tr in self._tracks.items()
        }
        return self.replace(tracks=tracks)

    def fill_gaps(self, max_gap: float) -> Demonstration:
        """Interpolate tracking gaps no longer than ``max_gap`` seconds (opt-in).

        Positions are interpolated linearly and orientations by slerp between the
        valid frames on either side of a gap. Longer gaps, and gaps at the start or
        end of the recording, stay missing.

        Parameters
        ----------
        max_gap : float
            Longest gap to fill, seconds: the time between the last valid frame
            before the gap and the first valid frame after it.
        """
        if max_gap < 0:
            raise DemonstrationError(f"max_gap must be >= 0 s, got {max_gap}")
        tracks = {
            n: _interpolate_track(self.t, tr, self.t, max_gap) for n, tr in self._tracks.items()
        }
        return self.replace(tracks=tracks)

    def resample(
        self, rate: float, *, max_gap: float = 0.1, start: float | None = None
    ) -> Demonstration:
        """Resample every body onto a regular time axis.

        Positions are interpolated linearly, orientations by slerp, never across a
        tracking gap longer than ``max_gap``: samples inside such a gap are invalid.

        Parameters
        ----------
        rate : float
            New frame rate, Hz.
        max_gap : float
            Longest interval between two valid source frames to interpolate across,
            seconds. Consecutive source frames are always bridged, whatever the
            source rate.
        start : float, optional
            First time stamp of the new axis, seconds; defaults to the first frame.
        """
        if not np.isfinite(rate) or rate <= 0:
            raise DemonstrationError(f"resampling rate must be positive, got {rate}")
        t0 = float(self.t[0]) if start is None else float(start)
        n = int(np.floor((self.t[-1] - t0) * rate + 1e-9)) + 1
        if n < 1:
            raise DemonstrationError(f"resampling start {t0} s lies after the last frame")
        new_t = t0 + np.arange(n) / rate
        tracks = {
            n: _interpolate_track(self.t, tr, new_t, max_gap) for n, tr in self._tracks.items()
        }
        lab = clip_labels(self.labels, float(new_t[0]), float(new_t[-1]))
        return self.replace(
            t=new_t, tracks=tracks, labels=lab, meta={**self.meta, "resampled_hz": rate}
        )

    def equals(self, other: Demonstration, *, atol: float = 0.0) -> bool:
        """True when both hold the same bodies, metadata, labels and arrays (NaN = NaN)."""
        if self.body_names != other.body_names or self.bodies != other.bodies:
            return False
        if self.labels != other.labels or self.t.shape != other.t.shape:
            return False
        if not np.allclose(self.t, other.t, atol=atol, rtol=0):
            return False
        for n in self.body_names:
            a, b = self.track(n), other.track(n)
            if not np.array_equal(a.valid, b.valid):
                return False
            for x, y in ((a.pos, b.pos), (a.quat, b.quat)):
                if not np.allclose(x, y, atol=atol, rtol=0, equal_nan=True):
                    return False
        return True


# ---------------------------------------------------------------- validation
def _check_time(t: ArrayLike) -> FloatArray:
    arr = np.asarray(t, dtype=np.float64)
    if arr.ndim != 1:
        raise DemonstrationError(f"time axis must be 1-D, got shape {arr.shape}")
    if arr.size == 0:
        raise DemonstrationError("time axis is empty: a demonstration needs at least one frame")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise DemonstrationError(f"time axis: frame {bad[0]} is not finite ({arr[bad[0]]})")
    dec = np.flatnonzero(np.diff(arr) <= 0)
    if dec.size:
        i = int(dec[0]) + 1
        raise DemonstrationError(
            f"time axis not strictly increasing at frame {i}: "
            f"{arr[i - 1]:.9g} s then {arr[i]:.9g} s"
        )
    arr.setflags(write=False)
    return arr


def clip_labels(labels: Labels, t0: float, t1: float) -> Labels:
    """Labels clipped to ``[t0, t1]`` s: intervals cut; events and timed steps outside dropped."""
    inter = tuple(
        dataclasses.replace(i, start=max(i.start, t0), end=min(i.end, t1))
        for i in labels.interactions
        if i.end >= t0 and i.start <= t1
    )
    cons = tuple(c for c in labels.constraints if t0 <= c.time <= t1)
    plan = tuple(s for s in labels.plan if s.time is None or t0 <= s.time <= t1)
    return Labels(interactions=inter, constraints=cons, plan=plan)


def label_tolerance(t: FloatArray) -> float:
    """How far (s) a label may lie outside ``[t[0], t[-1]]``: half a frame, 1 µs at least."""
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return 0.5 * step + 1e-6


def _check_labels(labels: Labels, t: FloatArray) -> None:
    """Every label time finite and inside the recording, every interval ordered."""
    lo, hi = float(t[0]), float(t[-1])
    tol = label_tolerance(t)

    def inside(x: float, what: str) -> None:
        if not math.isfinite(x):
            raise DemonstrationError(f"{what}: time {x} is not finite")
        if not lo - tol <= x <= hi + tol:
            raise DemonstrationError(
                f"{what}: time {x:.9g} s lies outside the recording ({lo:.9g} to {hi:.9g} s)"
            )

    for i in labels.interactions:
        what = f"interaction label {i.a}-{i.b} [{i.start:.9g}, {i.end:.9g}] s"
        inside(i.start, what)
        inside(i.end, what)
        if i.start > i.end:
            raise DemonstrationError(f"{what}: starts after it ends")
    for c in labels.constraints:
        inside(c.time, f"constraint label {c.parent}->{c.child}")
        values = (*c.pos, *c.quat)
        if not all(math.isfinite(x) for x in values):
            raise DemonstrationError(
                f"constraint label {c.parent}->{c.child}: pose {values} is not finite"
            )
    for s in labels.plan:
        if s.time is not None:
            inside(s.time, f"plan step {s.parent}->{s.child}")


def _check_track(
    info: BodyInfo, n: int, pos: ArrayLike, quat: ArrayLike, valid: ArrayLike | None
) -> BodyTrack:
    name = info.name
    p = np.array(pos, dtype=np.float64, copy=True)
    q = np.array(quat, dtype=np.float64, copy=True)
    if p.shape != (n, 3):
        raise DemonstrationError(
            f"body {name!r}: positions must have shape ({n}, 3), got {p.shape}"
        )
    if q.shape != (n, 4):
        raise DemonstrationError(
            f"body {name!r}: quaternions must have shape ({n}, 4), got {q.shape}"
        )
    if not info.oriented:
        # Position-only track: the orientation is the identity by definition.
        q = np.where(np.all(np.isfinite(p), axis=1)[:, None], se3.quat_identity((n,)), np.nan)
    # A row sum is finite exactly when every entry is (one pass instead of two reductions).
    finite = np.isfinite(p.sum(axis=1) + q.sum(axis=1))
    if valid is None:
        v = finite
    else:
        v = np.array(valid, dtype=bool, copy=True)
        if v.shape != (n,):
            raise DemonstrationError(f"body {name!r}: valid must have shape ({n},), got {v.shape}")
        bad = np.flatnonzero(v & ~finite)
        if bad.size:
            raise DemonstrationError(
                f"body {name!r} frame {bad[0]}: marked valid but pose is not finite"
            )
    norm = np.sqrt(np.einsum("ij,ij->i", q, q))
    zero = np.flatnonzero(v & (norm < 1e-9))
    if zero.size:
        raise DemonstrationError(f"body {name!r} frame {zero[0]}: zero-norm quaternion")
    with np.errstate(invalid="ignore"):
        far = np.flatnonzero(v & (np.abs(p) > MAX_PLAUSIBLE_POSITION_M).any(axis=1))
    if far.size:
        i = int(far[0])
        raise DemonstrationError(
            f"body {name!r} frame {i}: position {np.abs(p[i]).max():.6g} m from the origin is "
            f"beyond {MAX_PLAUSIBLE_POSITION_M:g} m; are these millimetres read as metres?"
        )
    if info.oriented:
        with np.errstate(invalid="ignore"):
            bad_norm = np.flatnonzero(v & ~(np.abs(norm - 1.0) <= MAX_QUAT_NORM_ERROR))
        if bad_norm.size:
            i = int(bad_norm[0])
            raise DemonstrationError(
                f"body {name!r} frame {i}: quaternion has norm {norm[i]:.6g}; expected a unit "
                f"quaternion (within {MAX_QUAT_NORM_ERROR:g} of 1)"
            )
    # Renormalise only what is off: a stored unit quaternion must load bit-identical.
    off = v & (np.abs(norm - 1.0) > 1e-12)
    q[off] /= norm[off, None]
    if not v.all():
        p[~v] = np.nan
        q[~v] = np.nan
    for arr in (p, q, v):
        arr.setflags(write=False)
    return BodyTrack(info=info, pos=p, quat=q, valid=v)


def _interpolate_track(
    t_src: FloatArray, track: BodyTrack, t_new: FloatArray, max_gap: float
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Interpolate one body's valid samples at ``t_new`` without bridging long gaps."""
    idx = np.flatnonzero(track.valid)
    n = t_new.size
    pos = np.full((n, 3), np.nan)
    quat = np.full((n, 4), np.nan)
    valid = np.zeros(n, dtype=bool)
    if idx.size == 0:
        return pos, quat, valid
    ts = t_src[idx]
    ps = track.pos[idx]
    qs = se3.quat_make_continuous(track.quat[idx])
    hi = np.searchsorted(ts, t_new, side="left")
    exact = (hi < ts.size) & (ts[np.minimum(hi, ts.size - 1)] == t_new)
    inside = (hi > 0) & (hi < ts.size)
    lo_i = np.clip(hi - 1, 0, ts.size - 1)
    hi_i = np.clip(hi, 0, ts.size - 1)
    span = ts[hi_i] - ts[lo_i]
    # Consecutive source frames hold no gap, whatever the source rate.
    ok = inside & ((span <= max_gap) | (idx[hi_i] - idx[lo_i] == 1))
    w = np.where(ok, (t_new - ts[lo_i]) / np.where(span > 0, span, 1.0), 0.0)
    pos[ok] = ps[lo_i[ok]] + w[ok, None] * (ps[hi_i[ok]] - ps[lo_i[ok]])
    quat[ok] = se3.quat_slerp(qs[lo_i[ok]], qs[hi_i[ok]], w[ok])
    pos[exact] = ps[hi_i[exact]]
    quat[exact] = qs[hi_i[exact]]
    valid = ok | exact
    return pos, quat, valid


__all__ = [
    "BODY_KINDS",
    "CONSTRAINT_TYPES",
    "DOF_NAMES",
    "BodyInfo",
    "BodyTrack",
    "ConstraintEvent",
    "Demonstration",
    "FreeDofs",
    "InteractionInterval",
    "Labels",
    "PlanStep",
    "body_info_from_dict",
    "body_info_to_dict",
    "labels_from_dict",
    "labels_to_dict",
]


# ------------------------------------------------------------- serialisation
def body_info_to_dict(info: BodyInfo) -> dict[str, Any]:
    """JSON-able dict of a body's metadata (fields at their default omitted)."""
    return {
        k: v
        for k, v in dataclasses.asdict(info).items()
        if v is not None and not (k == "oriented" and v)
    }


def body_info_from_dict(d: Mapping[str, Any]) -> BodyInfo:
    """Inverse of :func:`body_info_to_dict`."""
    try:
        return BodyInfo(**d)
    except TypeError as exc:
        raise DemonstrationError(f"body metadata {dict(d)!r}: {exc}") from None


def labels_to_dict(labels: Labels) -> dict[str, Any]:
    """JSON-able dict of labels; exact inverse of :func:`labels_from_dict`."""
    return {
        "interactions": [dataclasses.asdict(i) for i in labels.interactions],
        "constraints": [
            {**dataclasses.asdict(c), "free_dofs": [list(r) for r in c.free_dofs.ranges()]}
            for c in labels.constraints
        ],
        "plan": [dataclasses.asdict(s) for s in labels.plan],
    }


def labels_from_dict(d: Mapping[str, Any]) -> Labels:
    """Labels from :func:`labels_to_dict` output; raises DemonstrationError when malformed."""
    try:
        inter = tuple(
            InteractionInterval(str(i["a"]), str(i["b"]), float(i["start"]), float(i["end"]))
            for i in d.get("interactions", [])
        )
        cons = tuple(
            ConstraintEvent(
                time=float(c["time"]),
                parent=str(c["parent"]),
                child=str(c["child"]),
                type=str(c["type"]),
                pos=tuple(float(x) for x in c["pos"]),  # type: ignore[arg-type]
                quat=tuple(float(x) for x in c["quat"]),  # type: ignore[arg-type]
                free_dofs=FreeDofs.from_array(c["free_dofs"]),
                symbol=c.get("symbol"),
                removed=bool(c.get("removed", False)),
            )
            for c in d.get("constraints", [])
        )
        plan = tuple(
            PlanStep(
                str(s["parent"]),
                str(s["child"]),
                s.get("symbol"),
                None if s.get("time") is None else float(s["time"]),
            )
            for s in d.get("plan", [])
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise DemonstrationError(f"malformed labels: {type(exc).__name__}: {exc}") from None
    return Labels(interactions=inter, constraints=cons, plan=plan)
