"""Small synthetic pick-and-place recordings with known interaction intervals.

For unit tests and benchmarks that must not depend on the full scene
generator: a *carrier* (a hand-like body, always moving smoothly) picks up
parts one after the other, carries each rigidly for a while and puts it down.
A part at rest keeps its last pose; while carried its pose is the carrier's
composed with the fixed grasp offset taken at the moment of the pick, so every
track is continuous. The planted intervals are the ground truth.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import BodyInfo, Demonstration, InteractionInterval, Labels


def _smooth_track(
    rng: np.random.Generator, t: FloatArray, *, amplitude: float, n_waves: int = 4
) -> tuple[FloatArray, FloatArray]:
    """A smooth, always-moving pose track: sums of random sinusoids (0.1–0.6 Hz)."""
    freqs = rng.uniform(0.1, 0.6, size=(n_waves, 6))
    phases = rng.uniform(0, 2 * np.pi, size=(n_waves, 6))
    amps = rng.uniform(0.5, 1.0, size=(n_waves, 6)) / n_waves
    waves = np.sum(amps[None] * np.sin(2 * np.pi * freqs[None] * t[:, None, None] + phases), 1)
    pos = np.array([0.5, 0.0, 1.0]) + amplitude * waves[:, :3]
    rotvec = 0.8 * waves[:, 3:]
    return pos, se3.quat_from_rotvec(rotvec)


def random_pick_place_demo(
    rng: np.random.Generator,
    *,
    n_parts: int = 1,
    duration: float = 20.0,
    rate: float = 120.0,
    picks_per_part: int = 2,
    noise_pos: float = 0.0,
    noise_rot: float = 0.0,
    missing: float = 0.0,
    offset: float = 1.5,
    hands: tuple[str, ...] = (),
    n_fingers: int = 3,
    pick_length: tuple[float, float] = (0.8, 2.5),
) -> Demonstration:
    """A carrier ``"carrier"`` (kind hand) picking parts ``"part0"…`` (kind part).

    With ``hands`` (e.g. ``("left", "right")``) there is one untracked carrier per
    hand, each pick made by a random hand, and the tracked bodies are that hand's
    ``n_fingers`` fingers (``"lh_f0"``…, kind finger, ``hand_body`` ``"lh"``),
    rigidly attached to their carrier a few centimetres apart; labels then hold
    one interval per finger and pick.

    Parameters
    ----------
    rng : numpy.random.Generator
    n_parts : int
    duration : float
        Seconds.
    rate : float
        Capture rate, Hz.
    picks_per_part : int
        Carried intervals per part; all intervals are disjoint in time,
        separated by at least 1 s.
    noise_pos : float
        Standard deviation of white position noise, metres.
    noise_rot : float
        Standard deviation of white rotation noise (rotation-vector components), radians.
    missing : float
        Fraction of frames lost per body, in bursts of 2–30 frames.
    offset : float
        Added to every x coordinate, metres (tests precision far from the origin).
    hands : tuple of {"left", "right"}
    pick_length : (float, float)
        Range of the carried intervals' lengths, seconds (capped by the room available).
    n_fingers : int
        Fingers per hand when ``hands`` is given.

    Returns
    -------
    Demonstration
        Labels: one :class:`InteractionInterval` ``("carrier", part, start, end)`` per pick.
    """

    n = round(duration * rate)
    t = np.arange(n) / rate
    sides = hands or ("carrier",)
    carriers = {}
    for side in sides:
        p_c, q_c = _smooth_track(rng, t, amplitude=0.3)
        p_c[:, 0] += offset
        carriers[side] = (p_c, q_c)
    n_int = n_parts * picks_per_part
    # Disjoint intervals: split [0.5, duration - 0.5] into n_int slots, one pick per slot.
    slots = np.linspace(0.5, duration - 0.5, n_int + 1)
    owner = rng.permutation(np.repeat(np.arange(n_parts), picks_per_part))
    intervals = []
    for k in range(n_int):
        room = slots[k + 1] - slots[k] - 1.0
        length = float(np.clip(rng.uniform(*pick_length), 0.3, max(room, 0.3)))
        s = float(slots[k] + 0.5 + rng.uniform(0, max(room - length, 0.0)))
        intervals.append((int(owner[k]), sides[int(rng.integers(len(sides)))], s, s + length))
    pos: dict[str, FloatArray] = {}
    quat: dict[str, FloatArray] = {}
    bodies: list[BodyInfo] = []
    fingers: dict[str, list[str]] = {}
    for side, (p_c, q_c) in carriers.items():
        if not hands:
            pos["carrier"], quat["carrier"] = p_c, q_c
            bodies.append(BodyInfo("carrier", kind="hand"))
            fingers[side] = ["carrier"]
            continue
        hb = f"{side[0]}h"
        fingers[side] = []
        r = q_c
        for i in range(n_fingers):
            name = f"{hb}_f{i}"
            off = np.array([0.03 * i, 0.02, -0.01 * i])
            pos[name] = p_c + se3.quat_rotate(r, off)
            quat[name] = se3.quat_multiply(r, se3.quat_from_rotvec([0.1 * i, 0.0, 0.2]))
            bodies.append(BodyInfo(name, kind="finger", hand=side, hand_body=hb))  # type: ignore[arg-type]
            fingers[side].append(name)
    labels: list[InteractionInterval] = []
    for j in range(n_parts):
        p = np.empty((n, 3))
        q = np.empty((n, 4))
        rest_p = np.array([offset + 0.2 * j, 0.4, 0.8])
        rest_q = se3.random_quat(rng)
        cur = 0
        for who, side, s, e in intervals:
            if who != j:
                continue
            p_c, q_c = carriers[side]
            i0 = int(np.ceil(s * rate))
            i1 = min(int(np.floor(e * rate)), n - 1)
            p[cur:i0] = rest_p
            q[cur:i0] = rest_q
            # Grasp offset: the part's pose in the carrier's frame at the pick.
            off_p, off_q = se3.relative_pose(p_c[i0], q_c[i0], rest_p, rest_q)
            seg = slice(i0, i1 + 1)
            p[seg] = p_c[seg] + se3.quat_rotate(q_c[seg], off_p)
            q[seg] = se3.quat_multiply(q_c[seg], off_q)
            rest_p, rest_q = p[i1].copy(), q[i1].copy()
            cur = i1 + 1
            labels.extend(
                InteractionInterval(f, f"part{j}", float(t[i0]), float(t[i1]))
                for f in fingers[side]
            )
        p[cur:] = rest_p
        q[cur:] = rest_q
        pos[f"part{j}"] = p
        quat[f"part{j}"] = q
    valid = {}
    for name in pos:
        if noise_pos > 0:
            pos[name] = pos[name] + noise_pos * rng.standard_normal((n, 3))
        if noise_rot > 0:
            dr = se3.quat_from_rotvec(noise_rot * rng.standard_normal((n, 3)))
            quat[name] = se3.quat_multiply(quat[name], dr)
        valid[name] = _random_valid(rng, n, missing)
    bodies += [BodyInfo(f"part{j}", kind="part") for j in range(n_parts)]
    labels.sort(key=lambda i: (i.start, i.a))
    return Demonstration(
        t,
        bodies,
        {k: np.where(valid[k][:, None], v, np.nan) for k, v in pos.items()},
        {k: np.where(valid[k][:, None], v, np.nan) for k, v in quat.items()},
        valid,
        labels=Labels(interactions=tuple(labels)),
    )


def _random_valid(rng: np.random.Generator, n: int, missing: float) -> NDArray[np.bool_]:
    valid = np.ones(n, dtype=bool)
    lost = 0
    target = int(missing * n)
    while lost < target:
        length = int(rng.integers(2, 31))
        i = int(rng.integers(0, n))
        seg = valid[i : i + length]
        lost += int(seg.sum())
        seg[:] = False
    return valid


__all__ = ["random_pick_place_demo"]
