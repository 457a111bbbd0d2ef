"""Joint type of the real tracks: thirdhand against a naive line-vs-circle fit and a peer.

On every shared real track of ``../shared/data`` (56: see
``research/scripts/constraint_type_table.py``), in one run with default flags, prints each
method's type accuracy and fits per second, per mechanism and in all.

- **thirdhand**: :func:`thirdhand.constraints.fit_constraint` (noise estimated).
- **naive**: a least-squares line (principal axis) and a least-squares circle
  (plane, then an algebraic circle in it); the one of smaller rms residual wins,
  ``fixed`` when the track spans under 1 cm.
- **ripl-articulation** (PyPI, ICRA 2024): ``solve_articulation_from_poses``
  fits one SE(3) twist to 6-DoF poses. It pins ``numpy<=1.26.4`` (thirdhand's
  dev tools need numpy 2) and is GPL-3.0, so it is not a dependency: pass
  ``--peer-python`` the interpreter of a separate environment holding it, and the
  oriented tracks are sent to it in a subprocess (a twist with a rotation part
  under 1 % of its norm is prismatic, else revolute; position-only tracks it
  cannot take).

Usage: ``python benchmarks/articulation_vs_peer.py [--data DIR] [--peer-python PY]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from thirdhand.constraints import fit_constraint

sys.path.insert(0, str(Path(__file__).parents[1] / "research" / "scripts"))
from constraint_type_table import naive_type, real_tracks

FloatArray = NDArray[np.float64]

PEER_CODE = r"""
import json, sys, time
import numpy as np
from scipy.spatial.transform import Rotation
from ripl_articulation import solve_articulation_from_poses
data = np.load(sys.argv[1])
out = {}
for key in data.files:
    pose = data[key]
    n = pose.shape[0]
    t_a = np.tile(np.eye(4), (n, 1, 1))
    t_b = np.tile(np.eye(4), (n, 1, 1))
    t_b[:, :3, :3] = Rotation.from_quat(pose[:, 3:]).as_matrix()
    t_b[:, :3, 3] = pose[:, :3]
    # The estimate is biased towards theta = 0 at w_T_a = w_T_b: express B in its first pose.
    t_b = np.linalg.inv(t_b[0]) @ t_b
    start = time.perf_counter()
    xi, _ = solve_articulation_from_poses(t_a, t_b)
    out[key] = {"xi": np.asarray(xi).tolist(), "seconds": time.perf_counter() - start}
print(json.dumps(out))
"""


def _rate(fn: object, inputs: list[tuple[FloatArray, FloatArray | None]], seconds: float) -> float:
    fits = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        for p, q in inputs:
            fn(p, q)  # type: ignore[operator]
        fits += len(inputs)
    return fits / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = Path(os.environ.get("THIRDHAND_DATA", Path(__file__).parents[2] / "shared/data"))
    parser.add_argument("--data", type=Path, default=default)
    parser.add_argument("--peer-python", type=Path, default=None)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()

    tracks = list(real_tracks(args.data))
    fit_constraint(tracks[0][2], tracks[0][3])  # warm-up (numba compilation)
    ours = {name: fit_constraint(p, q).type for name, _, p, q, _ in tracks}
    naive = {name: naive_type(p) for name, _, p, _, _ in tracks}
    peer: dict[str, str] = {}
    peer_seconds = 0.0
    if args.peer_python is not None:
        oriented = {
            f"t{i}": np.column_stack([p, q])[np.all(np.isfinite(p), axis=1)]
            for i, (_, _, p, q, _) in enumerate(tracks)
            if q is not None
        }
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "tracks.npz"
            np.savez(path, **oriented)
            res = subprocess.run(
                [str(args.peer_python), "-c", PEER_CODE, str(path)],
                capture_output=True,
                text=True,
                check=True,
            )
        got = json.loads(res.stdout.strip().splitlines()[-1])
        for key, v in got.items():
            xi = np.asarray(v["xi"])
            name = tracks[int(key[1:])][0]
            # gtsam's Pose3 tangent: rotation first, then translation.
            rot = float(np.linalg.norm(xi[:3]))
            peer[name] = "prismatic" if rot < 0.01 * float(np.linalg.norm(xi)) else "revolute"
            peer_seconds += float(v["seconds"])

    print(f"{'track':50s} {'true':10s} {'thirdhand':11s} {'naive':10s} {'peer':10s}")
    for name, kind, _, _, _ in tracks:
        print(f"{name:50s} {kind:10s} {ours[name]:11s} {naive[name]:10s} {peer.get(name, '-'):10s}")
    print()
    # Per mechanism: accuracy and fits/s of each method on that mechanism's tracks.
    seconds = args.seconds / 4.0
    mechanisms = list(dict.fromkeys(t[4] for t in tracks))
    print(
        "| mechanism | tracks | thirdhand | naive line-vs-circle | thirdhand fits/s | "
        "naive fits/s |"
    )
    print("|---|---|---|---|---|---|")
    worse = []
    for m in mechanisms:
        sub = [t for t in tracks if t[4] == m]
        r_ours = sum(ours[k] == t for k, t, _, _, _ in sub)
        r_naive = sum(naive[k] == t for k, t, _, _, _ in sub)
        inputs = [(p, q) for _, _, p, q, _ in sub]
        rate = _rate(fit_constraint, inputs, seconds)
        rate_naive = _rate(lambda p, q: naive_type(p), inputs, seconds)
        print(
            f"| {m} | {len(sub)} | {r_ours}/{len(sub)} | {r_naive}/{len(sub)} | "
            f"{rate:.1f} | {rate_naive:.1f} |"
        )
        if r_ours < r_naive:
            worse.append(m)
    n = len(tracks)
    right = sum(ours[k] == t for k, t, _, _, _ in tracks)
    right_naive = sum(naive[k] == t for k, t, _, _, _ in tracks)
    inputs = [(p, q) for _, _, p, q, _ in tracks]
    rate = _rate(fit_constraint, inputs, args.seconds)
    rate_naive = _rate(lambda p, q: naive_type(p), inputs, args.seconds)
    print(
        f"| **all** | {n} | **{right}/{n}** | {right_naive}/{n} | {rate:.1f} | {rate_naive:.1f} |"
    )
    print(
        f"\nthirdhand: {right}/{n}   naive line-vs-circle: {right_naive}/{n}   "
        f"ratio of accuracies {right / max(right_naive, 1):.2f}; "
        + ("thirdhand >= naive on every mechanism" if not worse else f"below naive on {worse}")
    )
    print(f"thirdhand {rate:8.1f} fits/s   naive {rate_naive:8.1f} fits/s")
    if peer:
        oriented_names = [k for k, _, _, q, _ in tracks if q is not None]
        right_peer = sum(peer[k] == t for k, t, _, _, _ in tracks if k in peer)
        right_ours = sum(ours[k] == t for k, t, _, _, _ in tracks if k in peer)
        rate_ours = _rate(
            fit_constraint, [(p, q) for k, _, p, q, _ in tracks if k in peer], args.seconds
        )
        rate_peer = len(oriented_names) / peer_seconds
        print(
            f"oriented tracks ({len(peer)}): thirdhand {right_ours}/{len(peer)}, "
            f"ripl-articulation {right_peer}/{len(peer)}; thirdhand {rate_ours:.1f} fits/s, "
            f"ripl-articulation {rate_peer:.1f} fits/s, ratio {rate_ours / rate_peer:.1f}x"
        )


if __name__ == "__main__":
    main()
