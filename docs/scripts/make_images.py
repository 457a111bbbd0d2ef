"""Make the pictures of the documentation from the demo's own outputs.

    python docs/scripts/make_images.py [DEMO_FOLDER]

DEMO_FOLDER is the output of ``make demo`` (default ``out/chair``; it runs
``thirdhand demo`` there first when the folder has no ``task.json``). Writes into
``docs/images/``:

- ``phases.png``: the demo's interaction-phase plot (``thirdhand segment --plot``),
  copied;
- ``keyframes.png``: the report's keyframe figure (every plan step's keyframe drawn
  with the parts), taken out of ``report/index.html``;
- ``execution.png``: the executed joint trajectory of ``execution.json``, each plan
  step shaded (matplotlib);
- ``review.png`` when ``--review`` is given: a screenshot of the review GUI on the
  demo's task (Debian's chromium through Playwright, as the browser tests do).

Every picture is made by thirdhand's own code on the demo's data, so a change of
the code shows in the pictures the next time this runs.
"""

from __future__ import annotations

import argparse
import base64
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
IMAGES = HERE.parent / "images"
#: Headless chromium with software WebGL, as the review GUI's browser tests run it.
CHROMIUM = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]


def _demo(folder: Path) -> None:
    if (folder / "task.json").is_file():
        return
    subprocess.run([sys.executable, "-m", "thirdhand", "demo", "-o", str(folder)], check=True)


def _report_images(folder: Path) -> dict[str, bytes]:
    """The report's figures by the heading above them (``Segmentation``, ``Keyframes``)."""
    html = (folder / "report" / "index.html").read_text(encoding="utf-8")
    found: dict[str, bytes] = {}
    pattern = (
        r"<h3>([^<]+)</h3>(?:<p>.*?</p>)?\s*<img src='data:image/png;base64,([A-Za-z0-9+/=]+)'"
    )
    for title, data in re.findall(pattern, html):
        found[title.strip()] = base64.b64decode(data)
    return found


def _execution_plot(folder: Path, target: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    run = json.loads((folder / "execution.json").read_text(encoding="utf-8"))
    t = np.asarray(run["t"])
    q = np.asarray(run["q"])
    fig, ax = plt.subplots(figsize=(9, 3.2), dpi=100)
    for j, name in enumerate(run["joint_names"]):
        ax.plot(t, q[:, j], lw=1, label=name)
    top = float(q.max()) + 0.3
    for k, step in enumerate(run["steps"]):  # in the order the arm did them
        spans = [s for s in run["segments"] if s.get("step") == step["index"]]
        if spans:
            t0 = min(s["t_start"] for s in spans)
            t1 = max(s["t_end"] for s in spans)
            ax.axvspan(t0, t1, color="0.92" if k % 2 else "0.84", zorder=0)
            ax.text((t0 + t1) / 2, top, step["child"], ha="center", va="bottom", fontsize=8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("joint angle (rad)")
    ax.legend(fontsize=7, ncol=4, loc="lower right")
    ax.set_title(f"{run['robot']}: the learned plan executed, {len(run['steps'])} steps")
    fig.tight_layout()
    fig.savefig(target)
    plt.close(fig)


def _review_screenshot(folder: Path, target: Path) -> None:
    import socket
    import tempfile
    import time

    from playwright.sync_api import TimeoutError as PlaywrightTimeout
    from playwright.sync_api import sync_playwright

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with tempfile.TemporaryDirectory() as tmp:
        light = Path(tmp) / "light.toml"
        light.write_text("[review]\nlight = true\n", encoding="utf-8")  # software WebGL
        command = [sys.executable, "-m", "thirdhand", "review", str(folder / "task.json")]
        command += ["--port", str(port), "--config", str(light)]
        server = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM)
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                for _ in range(60):  # the server imports its stage first
                    try:
                        page.goto(f"http://127.0.0.1:{port}")
                        break
                    except Exception:
                        time.sleep(1.0)
                page.get_by_role("button", name="Save", exact=True).wait_for(timeout=120_000)
                notice = page.locator(".mantine-Notification-root", has_text="Software WebGL")
                try:
                    notice.locator("button").click(timeout=3000)
                except PlaywrightTimeout:
                    pass
                time.sleep(3.0)  # let software WebGL draw
                page.screenshot(path=str(target), timeout=120_000)
                browser.close()
        finally:
            server.terminate()
            server.wait(timeout=30)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("demo", nargs="?", default="out/chair", type=Path)
    parser.add_argument("--review", action="store_true", help="Also screenshot the review GUI.")
    args = parser.parse_args(argv)
    _demo(args.demo)
    IMAGES.mkdir(exist_ok=True)
    shutil.copyfile(args.demo / "phases.png", IMAGES / "phases.png")
    figures = _report_images(args.demo)
    (IMAGES / "keyframes.png").write_bytes(figures["Keyframes"])
    _execution_plot(args.demo, IMAGES / "execution.png")
    if args.review:
        _review_screenshot(args.demo, IMAGES / "review.png")
    print(f"pictures written to {IMAGES}")


if __name__ == "__main__":
    main()
