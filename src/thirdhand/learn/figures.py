"""The plan stage's figures, for a summary printed or saved by a command."""

from __future__ import annotations

from typing import Any

from thirdhand.learn.results import Learned


def plan_figures(result: Learned) -> tuple[dict[str, Any], str]:
    """The plan stage's figures for a summary: a JSON-able block and one line.

    The block has the root, the steps and the first demonstration's constraints,
    and, when that demonstration has ground-truth constraints (a synthetic scene),
    the mean pose error of the learned ones (``pos_error_cm``, ``rot_error_deg``).
    """
    block: dict[str, Any] = {
        "root": result.plan.root,
        "steps": [str(s) for s in result.plan.steps],
        "constraints": [
            {
                "child": i.child,
                "parent": i.parent,
                "type": i.type,
                "start": i.start,
                "symbol": i.symbol,
            }
            for i in result.instances[0]
        ],
    }
    truth = result.demos[0].labels.constraints
    if truth:
        from thirdhand.metrics import pose_errors

        errs = pose_errors(result.instances[0], truth)
        if errs:
            block["pos_error_cm"] = 100 * float(sum(e[0] for e in errs) / len(errs))
            block["rot_error_deg"] = float(sum(e[1] for e in errs) / len(errs))
    line = f"plan: {len(result.plan.steps)} steps " + ", ".join(block["steps"])
    if "pos_error_cm" in block:
        line += f" (pose error {block['pos_error_cm']:.2f} cm, {block['rot_error_deg']:.2f}°)"
    return block, line
