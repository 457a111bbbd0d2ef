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
from thirdhand.demonstration import BodyInfo, Demonstration, InteractionInterval, Labels

FloatArray = NDArray[np.float64]


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
    from scipy.spatial.transform import Rotation

    return pos, Rotation.from_rotvec(rotvec).as_quat()


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
) -> Demonstration:
    """A carrier ``"carrier"`` (kind hand) picking parts ``"part0"…`` (kind part).

    Parameters
    ----------
    rng : numpy.random.Generator
    n_parts : int
    duration : float
        Seconds.
    rate : float
        Capture rate, Hz.
    picks_per_part : int
        Carried intervals per part; all intervals are disjoint in time (one
        carrier), 0.8–2.5 s long, separated by at least 1 s.
    noise_pos : float
        Standard deviation of white position noise, metres.
    noise_rot : float
        Standard deviation of white rotation noise (rotation-vector components), radians.
    missing : float
        Fraction of frames lost per body, in bursts of 2–30 frames.
    offset : float
        Added to every x coordinate, metres (tests precision far from the origin).

    Returns
    -------
    Demonstration
        Labels: one :class:`InteractionInterval` ``("carrier", part, start, end)`` per pick.
    """
    from scipy.spatial.transform import Rotation

    n = round(duration * rate)
    t = np.arange(n) / rate
    p_c, q_c = _smooth_track(rng, t, amplitude=0.3)
    p_c[:, 0] += offset
    n_int = n_parts * picks_per_part
    # Disjoint intervals: split [0.5, duration - 0.5] into n_int slots, one pick per slot.
    slots = np.linspace(0.5, duration - 0.5, n_int + 1)
    owner = rng.permutation(np.repeat(np.arange(n_parts), picks_per_part))
    intervals = []
    for k in range(n_int):
        room = slots[k + 1] - slots[k] - 1.0
        length = float(np.clip(rng.uniform(0.8, 2.5), 0.3, max(room, 0.3)))
        s = float(slots[k] + 0.5 + rng.uniform(0, max(room - length, 0.0)))
        intervals.append((int(owner[k]), s, s + length))
    pos, quat, labels = {"carrier": p_c}, {"carrier": q_c}, []
    r_c = Rotation.from_quat(q_c)
    for j in range(n_parts):
        p = np.empty((n, 3))
        q = np.empty((n, 4))
        rest_p = np.array([offset + 0.2 * j, 0.4, 0.8])
        rest_q = se3.random_quat(rng)
        cur = 0
        for who, s, e in intervals:
            if who != j:
                continue
            i0 = int(np.ceil(s * rate))
            i1 = min(int(np.floor(e * rate)), n - 1)
            p[cur:i0] = rest_p
            q[cur:i0] = rest_q
            # Grasp offset: the part's pose in the carrier's frame at the pick.
            off_p, off_q = se3.relative_pose(p_c[i0], q_c[i0], rest_p, rest_q)
            seg = slice(i0, i1 + 1)
            p[seg] = p_c[seg] + r_c[seg].apply(off_p)
            q[seg] = (r_c[seg] * Rotation.from_quat(off_q)).as_quat()
            rest_p, rest_q = p[i1].copy(), q[i1].copy()
            cur = i1 + 1
            labels.append(InteractionInterval("carrier", f"part{j}", t[i0], t[i1]))
        p[cur:] = rest_p
        q[cur:] = rest_q
        pos[f"part{j}"] = p
        quat[f"part{j}"] = q
    valid = {}
    for name in pos:
        if noise_pos > 0:
            pos[name] = pos[name] + noise_pos * rng.standard_normal((n, 3))
        if noise_rot > 0:
            dr = Rotation.from_rotvec(noise_rot * rng.standard_normal((n, 3)))
            quat[name] = (Rotation.from_quat(quat[name]) * dr).as_quat()
        valid[name] = _random_valid(rng, n, missing)
    bodies = [BodyInfo("carrier", kind="hand")] + [
        BodyInfo(f"part{j}", kind="part") for j in range(n_parts)
    ]
    labels.sort(key=lambda i: i.start)
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
