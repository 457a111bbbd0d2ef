"""Hostile command lines: nonsense options and malformed inputs.

Every case must end in ONE line ``thirdhand: error: <what and where>`` on stderr
and exit status 1 (2 for a usage error): no traceback (an exception escaping
``main`` fails the test), no hang, no silent default, no exit 0.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import call
from thirdhand import BodyInfo, Demonstration, io, se3
from thirdhand.taskfile import SCHEMA, TaskFile, save_task


def small_demo(n: int = 25, seed: int = 1) -> Demonstration:
    rng = np.random.default_rng(seed)
    return Demonstration(
        np.arange(n) / 120.0,
        [BodyInfo("seat"), BodyInfo("leg")],
        {"seat": rng.normal(size=(n, 3)), "leg": rng.normal(size=(n, 3))},
        {"seat": se3.random_quat(rng, n), "leg": se3.random_quat(rng, n)},
    )


def task_doc() -> dict:
    return {
        "schema": SCHEMA,
        "objects": [{"name": "seating"}, {"name": "leg1"}, {"name": "leg2"}],
        "constraints": [
            {"id": "c1", "parent": "seating", "child": "leg1", "type": "fixed"},
            {"id": "c2", "parent": "seating", "child": "leg2", "type": "fixed"},
        ],
        "plan": [
            {"parent": "seating", "child": "leg1", "constraint": "c1"},
            {"parent": "seating", "child": "leg2", "constraint": "c2"},
        ],
    }


def csv_variant(base: str, kind: str) -> str:
    """A Motive CSV broken in one of the ways a careless export or copy breaks it."""
    lines = base.split("\n")
    frame_row = next(i for i, s in enumerate(lines) if s.startswith("Frame,"))
    if kind == "moved_header":  # the Frame,Time row moved below 20 data rows
        body = lines[frame_row + 1 :]
        return "\n".join(lines[:frame_row] + body[:20] + [lines[frame_row]] + body[20:])
    if kind == "cut_last_cell":
        return base.rstrip("\n")[:-5]
    row = lines[frame_row + 4].split(",")
    if kind == "inf_cell":
        row[3] = "inf"
    elif kind == "huge_quat":
        row[2] = "149112"
    elif kind == "cr_in_header":
        lines[frame_row - 3] = lines[frame_row - 3].replace(",seat,", ",se\rat,", 1)
    lines[frame_row + 4] = ",".join(row)
    return "\n".join(lines)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("hostile")
    out = {"dir": d, "demo": d / "demo.parquet", "csv": d / "demo.csv", "task": d / "task.json"}
    demo = small_demo()
    io.save(demo, out["demo"])
    io.save(demo, out["csv"])
    save_task(TaskFile.model_validate(task_doc()), out["task"])
    base = out["csv"].read_text()
    for kind in ("moved_header", "cut_last_cell", "inf_cell", "huge_quat", "cr_in_header"):
        out[kind] = d / f"{kind}.csv"
        out[kind].write_text(csv_variant(base, kind), newline="")
    broken = {
        "cycle": lambda doc: doc["constraints"].append(
            {"id": "c3", "parent": "leg1", "child": "seating", "type": "fixed"}
        ),
        "two_parents": lambda doc: doc["constraints"].append(
            {"id": "c3", "parent": "leg2", "child": "leg1", "type": "fixed"}
        ),
        "huge_pos": lambda doc: doc["constraints"][0].update(pos=[1e12, 0.0, 0.0]),
    }
    for name, change in broken.items():
        doc = task_doc()
        change(doc)
        out[name] = d / f"{name}.json"
        out[name].write_text(json.dumps(doc))
    rng = np.random.default_rng(0)
    names = [f"b{i}" for i in range(300)]
    wide = Demonstration(
        np.arange(3) / 100.0,
        [BodyInfo(n) for n in names],
        {n: rng.normal(size=(3, 3)) for n in names},
        {n: se3.random_quat(rng, 3) for n in names},
    )
    out["wide"] = d / "wide.parquet"
    io.save(wide, out["wide"])
    out["existing_png"] = d / "existing.png"
    out["existing_png"].write_bytes(b"png")
    return out


#: (arguments with {placeholders} from ``files``, a fragment the error line must hold)
CASES: list[tuple[str, str]] = [
    ("synth chair -o {dir}/x.csv --rate inf", "--rate"),
    ("synth chair -o {dir}/x.csv --rate nan", "--rate"),
    ("synth chair -o {dir}/x.csv --rate 0", "--rate"),
    ("synth chair -o {dir}/x.csv --seed -1", "--seed"),
    ("synth nosuch -o {dir}/x.csv", "unknown scene"),
    ("demo -o {dir}/d --seed -3", "--seed"),
    ("synth chair -o {dir}/x.csv --seed abc", "--seed"),
    ("nosuch", "No such command"),
    ("info", "Missing argument"),
    ("convert {demo} {dir}/x.xyz", "extension"),
    ("convert {demo} {demo}", "also an input"),
    ("info {moved_header}", "above the 'Frame,Time"),
    ("info {cut_last_cell}", "ends inside a line"),
    ("info {inf_cell}", "not finite"),
    ("info {huge_quat}", "unit quaternion"),
    ("info {cr_in_header}", "carriage return"),
    ("info {dir}/missing.csv", "no such file"),
    ("segment {demo} -m {demo}", "not a segmentation model"),
    ("segment {demo} -m {task}", "thirdhand.segment/1"),
    ("segment {demo} --plot {dir}/x.csv", "figure"),
    ("segment {demo} --json {demo}", "also an input"),
    ("segment {wide}", "44850 body pairs"),
    ("learn {wide} -o {dir}/w.json", "44850 body pairs"),
    ("primitives library {demo} --body seat --skills 0", "--skills"),
    ("primitives library {demo} --body seat --skills 1000", "--skills"),
    ("primitives library {demo} --body seat --parser magic", "--parser"),
    (
        "primitives library {demo} --body seat --library {task}",
        "has no stages.primitives.skill_library",
    ),
    ("primitives library {demo} --body seat --plot {dir}/x.csv", "figure"),
    ("primitives library {demo} --body seat --plot {existing_png}", "--force"),
    ("irl learn {task} --legs -2", "--legs"),
    ("irl learn {task} --legs 5000", "--legs"),
    ("irl learn {task} --seed -1", "--seed"),
    ("irl learn --synth 100000", "--synth"),
    ("irl learn {cycle}", "cycle"),
    ("irl learn {task} --json {task}", "also an input"),
    ("execute {task} --seed -1", "--seed"),
    ("execute {huge_pos}", "beyond 1000 m"),
    ("execute {two_parents}", "one parent"),
    ("review {task} --port 99999", "--port"),
    ("review {task} --port -1", "--port"),
    ("review {task} --host 'bad host'", "--host"),
    ("review {cycle}", "cycle"),
    ("review {two_parents}", "one parent"),
    ("transfer {cycle} --to bench -o {dir}/t.json", "cycle"),
    ("transfer {task} --to bench -o {task}", "also an input"),
    ("constraints fit {demo} --parent seat --child seat", "both 'seat'"),
]


@pytest.mark.parametrize(("template", "fragment"), CASES, ids=[c[0][:60] for c in CASES])
def test_hostile_command_is_one_error_line(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], template: str, fragment: str
) -> None:
    import shlex

    args = shlex.split(template.format(**files))
    rc, out, err = call(capsys, *args)
    assert rc in (1, 2), (args, out, err)  # 2: a usage error (click's convention)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("thirdhand: error: "), err
    assert fragment in lines[0], lines[0]
    assert "Traceback" not in err and "wrote" not in out


def test_mediapipe_logs_do_not_reach_stderr(shared_data: Path) -> None:
    import subprocess
    import sys

    pytest.importorskip("mediapipe")
    video = shared_data / "faces" / "no_face.mp4"
    if not video.is_file():
        pytest.skip(f"no face video at {video}")
    proc = subprocess.run(
        [sys.executable, "-m", "thirdhand", "headpose", str(video)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert proc.returncode == 1
    # Without the redirection TFLite and absl print three lines before this one.
    assert proc.stderr.strip().splitlines() == [
        f"thirdhand: error: {video}: no face found in any of the 95 frames read"
    ]
