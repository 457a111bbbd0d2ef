"""What a written recording lost: the recording read back against the one written.

``convert`` writes to a temporary path, reads the result back with the same
readers ``info`` uses, and compares it with :func:`losses`. A format either
carries a recording exactly (times to the nanosecond, labels unsnapped, the
meta, every body's kind and poses to the precision of the format's numbers) or
the command names what it would lose and writes only when told (``--lossy``).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from thirdhand.demonstration import Demonstration, labels_to_dict

#: Seconds: frame and label times read back must lie this close (one nanosecond).
TIME_TOL_S = 1e-9
#: Metres: positions read back must lie this close (float32 storage of metres
#: holds 6e-8 relative, 60 nm at 1 m; no format stores coarser than a micrometre).
POS_TOL_M = 1e-6
#: Unit-quaternion distance ``1 - |q1·q2|`` allowed (float32 storage: ~1e-7).
QUAT_TOL = 1e-6
#: Meta keys a reader sets to describe the file it read, not the recording (an MLR
#: folder's tracker repair, ``mlr``, is of that folder).
FILE_KEYS = frozenset({"source", "format", "format_version", "ros_version", "labels_source", "mlr"})


def _json(value: Any) -> Any:
    """``value`` as JSON sees it (tuples as lists), for comparing meta; a value JSON
    cannot hold (a NaN) as its repr, which no file gives back."""
    try:
        return json.loads(json.dumps(value, default=str, allow_nan=False))
    except ValueError:
        return {"not JSON": repr(value)}


def _label_times(d: dict[str, Any]) -> list[tuple[str, float]]:
    """Every time in a labels document, with where it sits (``interactions[3].start``)."""
    out: list[tuple[str, float]] = []

    def walk(node: Any, where: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{where}.{k}" if where else str(k))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, f"{where}[{i}]")
        elif isinstance(node, float):
            out.append((where, node))

    walk(d, "")
    return out


def _strip_floats(node: Any) -> Any:
    if isinstance(node, dict):
        return {k: _strip_floats(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_strip_floats(v) for v in node]
    return None if isinstance(node, float) else node


def _label_losses(src: Demonstration, back: Demonstration) -> list[str]:
    a, b = labels_to_dict(src.labels), labels_to_dict(back.labels)
    if a == b:
        return []
    if _strip_floats(a) != _strip_floats(b):
        counts = {k: len(v) for k, v in a.items() if isinstance(v, list) and v}
        kept = {k: len(v) for k, v in b.items() if isinstance(v, list) and v}
        shown = ", ".join(f"{k} {n}→{kept.get(k, 0)}" for k, n in counts.items())
        return [f"the labels ({shown or 'changed'})"]
    ta, tb = _label_times(a), _label_times(b)
    moved = max((abs(x - y) for (_, x), (_, y) in zip(ta, tb, strict=True)), default=0.0)
    if moved <= TIME_TOL_S:
        return []
    return [f"the label times (moved by up to {moved * 1e3:.3g} ms, onto frames)"]


def _meta_losses(src: Demonstration, back: Demonstration) -> list[str]:
    a = {k: v for k, v in (src.meta or {}).items() if k not in FILE_KEYS}
    b = back.meta or {}
    missing = [k for k in a if k not in b]
    changed = [k for k in a if k in b and _json(a[k]) != _json(b[k])]
    out = []
    if missing:
        out.append(f"the meta {', '.join(missing)}")
    if changed:
        out.append(f"the meta {', '.join(changed)} (changed)")
    return out


def losses(src: Demonstration, back: Demonstration) -> list[str]:
    """What ``back`` (a recording read back) lost of ``src``, each in a few words; [] if nothing.

    Parameters
    ----------
    src : Demonstration
        The recording written.
    back : Demonstration
        The same recording read back from the written file.

    Returns
    -------
    list of str
        Empty when bodies (names, kinds, hands, orientation), frame times (to
        :data:`TIME_TOL_S`), poses (to :data:`POS_TOL_M` and :data:`QUAT_TOL`),
        valid masks, labels (times to :data:`TIME_TOL_S`) and meta (but the keys
        naming the file, :data:`FILE_KEYS`) came back.
    """
    out: list[str] = []
    names, kept = src.body_names, set(back.body_names)
    gone = [n for n in names if n not in kept]
    if gone:
        out.append(f"the bodies {', '.join(gone)}")
    extra = [n for n in back.body_names if n not in set(names)]
    if extra:
        out.append(f"the body names (read back as {', '.join(extra)})")
    info = {b.name: b for b in back.bodies}
    changed = [b.name for b in src.bodies if b.name in info and info[b.name] != b]
    if changed:
        out.append(f"the body kinds, hands or orientation of {', '.join(changed)}")
    if back.n_frames != src.n_frames:
        out.append(f"the frames ({src.n_frames} written, {back.n_frames} read back)")
        return out + _label_losses(src, back) + _meta_losses(src, back)
    dt = float(np.max(np.abs(back.t - src.t), initial=0.0))
    if dt > TIME_TOL_S:
        out.append(f"the frame times (moved by up to {dt * 1e3:.3g} ms)")
    dp = dq = 0.0
    masks = []
    for n in names:
        if n not in kept:
            continue
        va, vb = src.valid(n), back.valid(n)
        if not np.array_equal(va, vb):
            masks.append(n)
        both = va & vb
        if both.any():
            dp = max(dp, float(np.max(np.abs(back.pos(n)[both] - src.pos(n)[both]))))
            if src.info(n).oriented and back.info(n).oriented:
                dot = np.abs(np.sum(back.quat(n)[both] * src.quat(n)[both], axis=1))
                dq = max(dq, float(np.max(1.0 - dot)))
    if masks:
        out.append(f"which frames are tracked ({', '.join(masks)})")
    if not dp <= POS_TOL_M:
        out.append(f"position precision (off by up to {dp * 1e3:.3g} mm)")
    if not dq <= QUAT_TOL:
        out.append(f"orientation precision (1-|q·q'| up to {dq:.2g})")
    return out + _label_losses(src, back) + _meta_losses(src, back)


__all__ = ["FILE_KEYS", "POS_TOL_M", "QUAT_TOL", "TIME_TOL_S", "losses"]
