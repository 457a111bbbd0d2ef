"""Time ``thirdhand.io.motive.read`` against ``pandas.read_csv`` on the same Motive export.

Writes a 10-minute, 120 Hz take of 20 rigid bodies (Rotation X Y Z W, Position
X Y Z, Mean Marker Error per body; metres rounded to six decimals as Motive
rounds them, though written without Motive's trailing zeros, so the file is a
little smaller than Motive's; about 2 % of each body's frames blank, in gaps)
into a temporary folder, then
reads it with thirdhand (header parsing, validation, a full ``Demonstration``)
and with pandas (the numeric block only: ``skiprows`` = the header's length).
Each reader runs a few times, interleaved; the best time of each is reported.

Usage: ``python benchmarks/motive_load.py [--minutes 10] [--bodies 20] [--repeat 3]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from thirdhand.io import motive

RATE = 120.0
HEADER_LINES = 7  # key/value line, blank line, Type, Name, ID, component, Frame,Time


def write_take(path: Path, *, minutes: float, n_bodies: int, seed: int = 0) -> int:
    """Write a synthetic Motive 1.23 export; returns the number of data rows."""
    rng = np.random.default_rng(seed)
    n = round(minutes * 60 * RATE)
    frames = np.arange(n)
    t = np.round(frames / RATE, 6)
    kv = (
        f"Format Version,1.23,Take Name,bench,Take Notes,,Capture Frame Rate,{RATE:.6f},"
        f"Export Frame Rate,{RATE:.6f},Capture Start Time,2026-11-22 03.00.00.000 AM,"
        f"Capture Start Frame,0,Total Frames in Take,{n},Total Exported Frames,{n},"
        "Rotation Type,Quaternion,Length Units,Meters,Coordinate Space,Global"
    )
    rows: list[list[str]] = [[""] * 2 for _ in range(4)] + [["Frame", "Time (Seconds)"]]
    rows[0][1], rows[1][1], rows[2][1] = "Type", "Name", "ID"
    comps = ["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"]
    axes = ["X", "Y", "Z", "W", "X", "Y", "Z", ""]
    arrays: dict[str, pa.Array] = {"f": pa.array(frames), "t": pa.array(t)}
    s = np.linspace(0, 2 * np.pi, n)
    for b in range(n_bodies):
        name = f"body{b:02d}"
        rows[0] += ["Rigid Body"] * 8
        rows[1] += [name] * 8
        rows[2] += [f"{0xA000 + b:X}"] * 8
        rows[3] += comps
        rows[4] += axes
        q = rng.normal(size=4) + 0.05 * np.stack([np.sin(s * (k + 1)) for k in range(4)], axis=1)
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        p = rng.uniform(-2, 2, 3) + 0.3 * np.stack([np.cos(s * (k + 2)) for k in range(3)], axis=1)
        err = rng.uniform(0, 0.001, (n, 1))
        gap = np.zeros(n, bool)
        for start in rng.integers(0, n - 60, size=max(1, n // 2400)):
            gap[start : start + rng.integers(5, 60)] = True
        values = np.round(np.hstack([q, p, err]), 6)
        for k in range(8):
            arrays[f"{name}_{k}"] = pa.array(values[:, k], mask=gap)
    with open(path, "wb") as fh:
        header = [kv, ""] + [",".join(r) for r in rows]
        fh.write(("\n".join(header) + "\n").encode())
        pacsv.write_csv(pa.table(arrays), fh, pacsv.WriteOptions(include_header=False))
    return n


def best_of(fn: Callable[[], object], repeat: int) -> float:
    """Shortest wall-clock time of ``repeat`` calls, seconds."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    """Write the take, time both readers, print the table."""
    import pandas as pd

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--bodies", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "take.csv"
        n = write_take(path, minutes=args.minutes, n_bodies=args.bodies)
        demo = motive.read(path)
        frame = pd.read_csv(path, skiprows=HEADER_LINES, header=None)
        assert frame.shape == (n, 2 + 8 * args.bodies), frame.shape
        assert demo.n_frames == n and len(demo) == args.bodies
        got = demo.pos("body00")[:, 0]
        want = frame.iloc[:, 6].to_numpy()
        assert np.array_equal(got, want, equal_nan=True), "thirdhand and pandas disagree"
        del frame, demo
        times = {"thirdhand": float("inf"), "pandas": float("inf")}
        for _ in range(args.repeat):  # interleaved, so load changes hit both alike
            times["thirdhand"] = min(times["thirdhand"], best_of(lambda: motive.read(path), 1))
            times["pandas"] = min(
                times["pandas"],
                best_of(lambda: pd.read_csv(path, skiprows=HEADER_LINES, header=None), 1),
            )
        size_mb = path.stat().st_size / 1e6
    ratio = times["thirdhand"] / times["pandas"]
    print(f"Motive CSV load: {args.minutes:g} min at {RATE:g} Hz, {args.bodies} rigid bodies")
    print(f"{'file size':<22}{size_mb:>10.1f} MB")
    print(f"{'rows':<22}{n:>10d}")
    print(f"{'columns':<22}{2 + 8 * args.bodies:>10d}")
    print(f"{'thirdhand (best of ' + str(args.repeat) + ')':<22}{times['thirdhand']:>10.3f} s")
    print(f"{'pandas (best of ' + str(args.repeat) + ')':<22}{times['pandas']:>10.3f} s")
    print(f"{'ratio thirdhand/pandas':<22}{ratio:>10.2f} x   (target <= 1.5 x)")


if __name__ == "__main__":
    main()
