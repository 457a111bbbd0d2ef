"""Figure in the style of the report's Fig. 3: ground truth vs Viterbi, one row per pair.

matplotlib is imported lazily (optional dependency ``thirdhand[plot]``).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from thirdhand.errors import ThirdhandError
from thirdhand.segment.pipeline import SegmentationResult


def _spans(ax: Any, labels: Any, edges: Any, y: float, h: float, color: str) -> None:
    from thirdhand.segment.intervals import runs

    for a, b in runs(np.asarray(labels)):
        ax.broken_barh([(edges[a], edges[b] - edges[a])], (y, h), color=color, linewidth=0)


def plot_phases(
    result: SegmentationResult,
    path: str | os.PathLike[str],
    *,
    max_rows: int = 40,
    only_labelled: bool = True,
) -> None:
    """Write a PNG: per pair, the true phases (top strip), the Viterbi phases (bottom
    strip) and the marginal probability (line).

    Parameters
    ----------
    result : SegmentationResult
    path : path-like
        PNG file to write.
    max_rows : int
        Most rows drawn (pairs with ground-truth interactions first).
    only_labelled : bool
        Skip pairs that neither have a true nor a predicted interaction.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - optional dependency
        raise ThirdhandError("plotting needs matplotlib: pip install 'thirdhand[plot]'") from None
    rows: list[tuple[str, Any, Any, Any]] = []
    for h in result.hands:
        rows.append((f"{h.hand} · {h.object}", h.truth, h.label, None))
    for p in result.pairs:
        rows.append((f"{p.a} · {p.b}", p.truth, p.label, p.probability))
    if only_labelled:
        rows = [r for r in rows if np.any(r[2]) or (r[1] is not None and np.any(r[1]))]
    rows.sort(key=lambda r: -int(r[1] is not None and bool(np.any(r[1]))))
    rows = rows[:max_rows] or [("(no interaction found)", None, np.zeros(0, int), None)]
    edges = result.edges
    fig, ax = plt.subplots(figsize=(11, 0.45 * len(rows) + 1.0))
    for i, (_, truth, label, prob) in enumerate(rows):
        y0 = len(rows) - 1 - i
        if truth is not None:
            _spans(ax, truth, edges, y0 + 0.52, 0.33, "tab:green")
        _spans(ax, label, edges, y0 + 0.12, 0.33, "tab:blue")
        if prob is not None:
            ax.plot(result.times, y0 + 0.1 + 0.8 * np.nan_to_num(prob), color="k", lw=0.5)
    ax.set_yticks(np.arange(len(rows)) + 0.5)
    ax.set_yticklabels([r[0] for r in rows][::-1], fontsize=7)
    ax.set_ylim(0, len(rows))
    ax.set_xlim(edges[0], edges[-1])
    ax.set_xlabel("time (s)")
    ax.set_title("interaction phases: ground truth (green, top) vs Viterbi (blue, bottom)")
    fig.tight_layout()
    fig.savefig(os.fspath(path), dpi=110)
    plt.close(fig)


__all__ = ["plot_phases"]
