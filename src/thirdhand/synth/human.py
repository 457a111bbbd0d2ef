"""The human: hands with tracked thumb, index and middle fingertips, and a head.

A hand is a virtual frame ``H`` that is not tracked itself: origin at the centre
of the grasp, ``z`` the approach direction (from the palm towards the object),
``y`` the closing direction (from the thumb towards the fingers), ``x = y × z``.
The tracked fingertip sensors sit on the nails, at fixed offsets in ``H`` that
depend on the aperture (distance between the thumb and finger pads, metres):
the fingers open and close by changing the aperture, and curl slightly with it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo
from thirdhand.errors import ThirdhandError
from thirdhand.synth.motion import PosePath, Tremor, hold_motion, min_jerk, phase, quat_exp

FINGERS: tuple[str, ...] = ("thumb", "index", "middle")
#: Nail sensor above the finger pad, metres.
NAIL = 0.009
#: Extra opening beyond the object's width before closing, metres.
PREGRASP_OPENING = 0.045
#: Aperture of a relaxed hand, metres.
RELAXED_APERTURE = 0.05
_ALONG = np.array([0.0, 0.014, -0.012])  # fingertip spread along x_H, metres
_DEPTH = np.array([0.0, 0.0, 0.006])  # middle finger reaches a little further, metres
_SIDE = np.array([-1.0, 1.0, 1.0])  # thumb on -y_H, fingers on +y_H
_CURL = 2.5  # curl angle per metre of closing, radians


def finger_offsets(aperture: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Fingertip sensor poses in the hand frame for apertures ``a`` (n,) metres.

    Returns
    -------
    pos : ndarray, shape (n, 3 fingers, 3), metres, hand frame
    quat : ndarray, shape (n, 3 fingers, 4), x y z w, hand frame
    """
    a = np.atleast_1d(np.asarray(aperture, dtype=np.float64))
    half = 0.5 * a[:, None] + NAIL
    shape = (a.size, len(FINGERS))
    pos = np.stack(
        [np.broadcast_to(_ALONG, shape), _SIDE * half, np.broadcast_to(_DEPTH, shape)], axis=-1
    )
    curl = _CURL * (0.12 - a)[:, None] * _SIDE  # thumb curls the other way
    rv = np.zeros((*curl.shape, 3))
    rv[..., 0] = curl
    base = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]])
    return pos, se3.quat_multiply(base, quat_exp(rv))


def finger_pose_in_hand(index: int, aperture: float) -> tuple[FloatArray, FloatArray]:
    """One fingertip's pose in the hand frame at one aperture: (3,) and (4,)."""
    p, q = finger_offsets(aperture)
    return p[0, index], q[0, index]


@dataclass(frozen=True)
class FingerOnHand:
    """A fingertip following a moving hand while the aperture changes.

    Attributes
    ----------
    hand : PosePath
        The virtual hand frame's path, world frame.
    index : int
        0 thumb, 1 index, 2 middle.
    t0, t1 : float
        When the aperture changes, seconds.
    a0, a1 : float
        Aperture before and after, metres.
    jitter : Tremor or None
        The finger's own small motion, faded by the hand path's envelope.
    """

    hand: PosePath
    index: int
    t0: float
    t1: float
    a0: float
    a1: float
    jitter: Tremor | None = None

    def __call__(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        hp, hq = self.hand(t)
        a = self.a0 + (self.a1 - self.a0) * min_jerk(phase(t, self.t0, self.t1))
        op, oq = finger_offsets(a)
        p = hp + se3.quat_rotate(hq, op[:, self.index])
        if self.jitter is not None:
            env = np.sin(np.pi * phase(t, self.hand.t0, self.hand.t1))[:, None] ** 2
            p = p + env * self.jitter(t)
        return p, se3.quat_multiply(hq, oq[:, self.index])


@dataclass(frozen=True)
class Grasp:
    """Where a hand holds an object: the hand frame in the object's frame.

    Attributes
    ----------
    pos : ndarray, shape (3,), metres, object frame
    quat : ndarray, shape (4,), x y z w, object frame
    width : float
        Object thickness between the finger pads, metres (the closed aperture).
    """

    pos: FloatArray
    quat: FloatArray
    width: float


def grasp_from_axes(
    point: ArrayLike, approach: ArrayLike, closing: ArrayLike, width: float
) -> Grasp:
    """A grasp at ``point`` with hand ``z`` along ``approach`` and ``y`` along ``closing``.

    Parameters
    ----------
    point : array_like, shape (3,), metres, object frame
    approach : array_like, shape (3,), object frame; made orthogonal to nothing, unit-normalised
    closing : array_like, shape (3,), object frame; orthogonalised against ``approach``
    width : float, metres
    """
    z = np.asarray(approach, dtype=np.float64)
    z = z / np.linalg.norm(z)
    y = np.asarray(closing, dtype=np.float64)
    y = y - (y @ z) * z
    y = y / np.linalg.norm(y)
    x = np.cross(y, z)
    q = se3.quat_from_matrix(np.stack([x, y, z], axis=1))
    return Grasp(np.asarray(point, dtype=np.float64), q, float(width))


@dataclass
class Hand:
    """State of one hand while a scene is scripted.

    Attributes
    ----------
    name : str
        Prefix of its finger bodies, e.g. ``"rh"`` or ``"p2_lh"``.
    side : {"left", "right"}
    person : str
    rest : tuple of ndarray (3,), (4,)
        Resting pose of the hand frame, world.
    tremor : Tremor
    jitters : list of Tremor, one per finger
    idle_shift, idle_turn : Tremor or None
        The hand's own small motion while it waits (metres; radians, hand frame).
    hold_shift, hold_turn : Tremor or None
        The low-frequency motion it gives a part it holds at rest (metres;
        radians, world frame; see :class:`thirdhand.synth.motion.Wobble`).
    grip : list of Tremor, one per finger, or None
        How each fingertip flexes on a held object (metres, object frame; see
        :class:`thirdhand.synth.motion.Flex`); None: rigid.
    t_free : float
        End of the hand's last scripted motion, seconds.
    pose : tuple of ndarray (3,), (4,)
        Hand frame pose at ``t_free`` when not holding anything, world.
    aperture : float
        Aperture at ``t_free``, metres.
    holding : str or None
        Body the hand holds since ``grasp_time``.
    """

    name: str
    side: str
    person: str
    rest: tuple[FloatArray, FloatArray]
    tremor: Tremor
    jitters: list[Tremor]
    idle_shift: Tremor | None = None
    idle_turn: Tremor | None = None
    hold_shift: Tremor | None = None
    hold_turn: Tremor | None = None
    grip: list[Tremor] | None = None
    t_free: float = 0.0
    pose: tuple[FloatArray, FloatArray] = field(default_factory=lambda: (np.zeros(3), np.zeros(4)))
    aperture: float = RELAXED_APERTURE
    holding: str | None = None
    grasp: Grasp | None = None
    grasp_time: float = 0.0

    @property
    def fingers(self) -> list[str]:
        """Names of the finger bodies: ``<name>_thumb``, ``<name>_index``, ``<name>_middle``."""
        return [f"{self.name}_{f}" for f in FINGERS]

    def body_infos(self) -> list[BodyInfo]:
        """Metadata of the finger bodies."""
        return [
            BodyInfo(f, kind="finger", hand=self.side, hand_body=self.name, person=self.person)  # type: ignore[arg-type]
            for f in self.fingers
        ]


def make_hand(
    name: str, side: str, person: str, rest: tuple[FloatArray, FloatArray], rng: np.random.Generator
) -> Hand:
    """A hand at rest with its own tremor, finger jitter, idle and holding motion.

    Idle: a few millimetres and about two degrees at 0.3–3 Hz (a waiting hand is
    never still); holding: a few millimetres and a degree or two given to the part.
    """
    tremor = Tremor.random(rng)
    jitters = [Tremor.random(rng, amplitude=1.5e-4, drift=4e-4) for _ in FINGERS]
    idle_shift, idle_turn = hold_motion(rng, amplitude=3e-3, angle=np.deg2rad(2.5))
    hold_shift, hold_turn = hold_motion(rng, amplitude=2.5e-3, angle=np.deg2rad(1.5))
    hand = Hand(
        name=name,
        side=side,
        person=person,
        rest=rest,
        tremor=tremor,
        jitters=jitters,
        idle_shift=idle_shift,
        idle_turn=idle_turn,
        hold_shift=hold_shift,
        hold_turn=hold_turn,
    )
    hand.pose = (rest[0].copy(), rest[1].copy())
    return hand


def _scaled(tremor: Tremor | None, scale: float) -> Tremor | None:
    if tremor is None:
        return None
    return Tremor(tremor.freqs, tremor.amps * scale, tremor.phases)


@dataclass(frozen=True)
class HumanModel:
    """How much a person's hands move when they are not moving a part.

    Real resting fingers (a Polhemus G4 on the nails, ``toolbox_coop_4``) move by
    10–80 µm within a quarter second; the synthetic human's idle sway is a few
    millimetres. Both happen: a hand laid on the table is still, a hand held in
    the air waits swaying.

    Attributes
    ----------
    idle : float
        Scale of a waiting hand's sway and of the fingers' own jitter (1: a few
        millimetres and about two degrees; 0: perfectly still).
    hold : float
        Scale of the wobble a holding hand gives a part at rest (1: a few
        millimetres and a degree or two).
    tremor : float
        Scale of the tremor added to a hand's moves.
    grip : float
        Largest displacement per axis of a fingertip on the object it holds, metres
        (0: rigid, the default).
    seed : int
        Seeds the fingers' grip motion.
    """

    idle: float = 1.0
    hold: float = 1.0
    tremor: float = 1.0
    grip: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("idle", "hold", "tremor", "grip"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ThirdhandError(f"HumanModel.{name} must be finite and >= 0, got {v}")

    @classmethod
    def random(cls, rng: np.random.Generator) -> HumanModel:
        """A person drawn from still to restless: a third rest truly still."""
        idle = 0.0 if rng.random() < 1 / 3 else float(np.exp(rng.uniform(np.log(0.02), 0.0)))
        hold = float(np.exp(rng.uniform(np.log(0.2), np.log(1.5))))
        grip = float(np.exp(rng.uniform(np.log(2e-4), np.log(3e-3))))
        return cls(
            idle=idle,
            hold=hold,
            tremor=float(rng.uniform(0.3, 1.2)),
            grip=grip,
            seed=int(rng.integers(0, 2**31)),
        )

    def apply(self, hands: Iterable[Hand]) -> None:
        """Scale the motions of ``hands`` (in place, before any is scripted)."""
        rng = np.random.default_rng(self.seed)
        for h in hands:
            if self.grip > 0:
                h.grip = [
                    Tremor(
                        rng.uniform(0.5, 3.0, 3),
                        self.grip * rng.uniform(0.3, 1.0, (3, 3)) / 3.0,
                        rng.uniform(0.0, 2.0 * np.pi, (3, 3)),
                    )
                    for _ in h.fingers
                ]
            h.idle_shift = _scaled(h.idle_shift, self.idle)
            h.idle_turn = _scaled(h.idle_turn, self.idle)
            h.jitters = [t for t in (_scaled(j, self.idle) for j in h.jitters) if t is not None]
            h.hold_shift = _scaled(h.hold_shift, self.hold)
            h.hold_turn = _scaled(h.hold_turn, self.hold)
            scaled = _scaled(h.tremor, self.tremor)
            assert scaled is not None
            h.tremor = scaled

    def to_meta(self) -> dict[str, Any]:
        """JSON-able parameters."""
        return dataclasses.asdict(self)
