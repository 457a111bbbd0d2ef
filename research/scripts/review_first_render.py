"""Time to first render of ``thirdhand review`` in Debian's headless Chromium, and its frame rate.

For each rendering mode (``--light`` and full), the script starts
``thirdhand review TASK --port 0`` as a child process, opens its URL in
``/usr/bin/chromium`` (software WebGL, SwiftShader, as the browser tests do),
and reports, in seconds from the command's start:

- ``server``: the start line printed (the scene and panels are built);
- ``panel``: the page shows the control panel (its Save button);
- ``parts``: the 3D view shows the parts: a screenshot of the view (left of the
  panel) has more than 2 % of its pixels as dark as a shaded part (luminance
  below 200 of 255; the background and the floor grid are lighter);

and the frame rate of the page (``requestAnimationFrame`` callbacks over 5 s with
the view idle). Shadows and the environment map make every software-WebGL
frame slow; ``--light`` drops them.

    python research/scripts/review_first_render.py [TASK] [--meshes DIR] [--runs N]

Without TASK the synthetic chair's ground-truth task is used. On a loaded
machine the figures are inflated; give the load average with them.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]
#: Luminance (0-255) below which a pixel counts as a shaded part.
DARK = 200
#: Share of the view's pixels that must be dark for the parts to count as drawn.
SHARE = 0.02


def _view_dark_share(png: bytes) -> float:
    from io import BytesIO

    from PIL import Image

    img = np.asarray(Image.open(BytesIO(png)).convert("L"), dtype=np.float64)
    view = img[:, : int(0.7 * img.shape[1])]  # left of the control panel
    return float(np.mean(view < DARK))


def measure(task: Path, meshes: list[Path], light: bool, browser: object) -> dict[str, float]:
    """One run: seconds to server, panel and parts, and the idle frame rate (Hz)."""
    import json
    import tempfile

    cfg = Path(tempfile.mkdtemp()) / "review.toml"
    cfg.write_text(
        f"[review]\nmeshes = {json.dumps([str(m) for m in meshes])}\n"
        f"light = {'true' if light else 'false'}\n"
    )
    cmd = [sys.executable, "-m", "thirdhand", "review", str(task), "--port", "0"]
    cmd += ["--config", str(cfg)]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
    page = None
    try:
        assert proc.stdout is not None
        line = ""
        for line in proc.stdout:
            if line.startswith("thirdhand review:"):
                break
        out = {"server": time.perf_counter() - t0}
        url = line.rsplit(" at ", 1)[1].split()[0]
        page = browser.new_page(viewport={"width": 1280, "height": 900})  # type: ignore[attr-defined]
        page.goto(url)
        page.get_by_role("button", name="Save", exact=True).wait_for(timeout=120_000)
        out["panel"] = time.perf_counter() - t0
        end = time.perf_counter() + 180.0
        while time.perf_counter() < end:
            if _view_dark_share(page.screenshot(timeout=120_000)) > SHARE:
                out["parts"] = time.perf_counter() - t0
                break
            time.sleep(0.1)
        frames = page.evaluate(
            """() => new Promise(done => {
                let n = 0; const t0 = performance.now();
                const tick = () => { n += 1;
                    if (performance.now() - t0 < 5000) requestAnimationFrame(tick);
                    else done(n / ((performance.now() - t0) / 1000)); };
                requestAnimationFrame(tick); })"""
        )
        out["fps"] = float(frames)
        return out
    finally:
        if page is not None:
            page.close()
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("task", nargs="?", type=Path)
    ap.add_argument("--meshes", type=Path, action="append", default=[])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args(argv)
    if not CHROMIUM.exists():
        print(f"{CHROMIUM} not found: install Debian's chromium package", file=sys.stderr)
        return 1
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        task = args.task
        if task is None:
            from thirdhand.synth import make_scene
            from thirdhand.synth.task import truth_task
            from thirdhand.taskfile import save_task

            task = Path(tmp) / "chair.task.json"
            save_task(truth_task(make_scene("chair", seed=0)), task)
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            try:
                for light in (True, False):
                    rows = [measure(task, args.meshes, light, browser) for _ in range(args.runs)]
                    name = "--light" if light else "full"
                    for key in ("server", "panel", "parts", "fps"):
                        vals = [r[key] for r in rows if key in r]
                        shown = ", ".join(f"{v:.2f}" for v in vals) or "never"
                        med = f"median {np.median(vals):.2f}" if vals else ""
                        unit = "Hz" if key == "fps" else "s"
                        print(f"{name:8s} {key:6s} {unit}: {shown}  {med}", flush=True)
            finally:
                browser.close()
    print(f"load average: {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
