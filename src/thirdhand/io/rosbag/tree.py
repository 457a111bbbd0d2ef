"""The tf tree: edges, root choice, and poses composed along it at given stamps."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thirdhand import se3
from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.errors import FormatError
from thirdhand.io.rosbag.collect import _frame_id, _Raw
from thirdhand.io.rosbag.timeline import _interpolate, _Series, _series


@dataclass
class _Tree:
    """The tf tree: per child frame its parent and sample series."""

    parent: dict[str, str]
    dynamic: dict[str, _Series]
    static: dict[str, _Series]

    def path(self, frame: str) -> list[str]:
        """Child frames from the tree's root down to ``frame`` (empty for the root)."""
        out: list[str] = []
        while frame in self.parent:
            out.append(frame)
            frame = self.parent[frame]
        return out[::-1]

    def root(self, frame: str) -> str:
        while frame in self.parent:
            frame = self.parent[frame]
        return frame

    def edge_at(self, child: str, t_ns: IntArray) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Pose of ``child`` in its parent at times ``t_ns``, shapes (n, 3), (n, 4), (n,)."""
        if child in self.dynamic:
            return _interpolate(self.dynamic[child], t_ns)
        st = self.static[child]
        i = np.clip(np.searchsorted(st.stamps, t_ns, side="right") - 1, 0, None)
        return st.pose[i, :3], st.pose[i, 3:], st.visible[i]

    def lookup(
        self, frame: str, t_ns: IntArray, *, base: str | None = None
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Pose of ``frame`` in its ancestor ``base`` (default the tree's root) at times ``t_ns``.

        Returns positions (n, 3), quaternions (n, 4) and ``ok`` (n,), False where a
        transform on the path is unknown at that time.
        """
        path = self.path(frame)
        if base is not None:
            path = path[len(self.path(base)) :]
        n = t_ns.size
        p, q, ok = np.zeros((n, 3)), se3.quat_identity((n,)), np.ones(n, dtype=bool)
        for i, child in enumerate(path):
            ep, eq, eok = self.edge_at(child, t_ns)
            p, q = (ep, eq) if i == 0 else se3.pose_compose(p, q, ep, eq)
            ok = ok & eok
        return p, q, ok


def _build_tree(raw: _Raw, src: Path) -> _Tree:
    tree = _Tree(parent={}, dynamic={}, static={})
    for child, edge in raw.edges.items():
        tree.parent[child] = edge.parent
        what = f"tf frame {child!r}"
        if edge.dynamic.stamps:
            tree.dynamic[child] = _series(edge.dynamic, src, what)
        else:
            tree.static[child] = _series(edge.static, src, what)
    for child in tree.parent:
        seen = {child}
        frame = child
        while frame in tree.parent:
            frame = tree.parent[frame]
            if frame in seen:
                raise FormatError(src, f"tf frames form a cycle through {frame!r}", where="tf")
            seen.add(frame)
    return tree


def _choose_root(tree: _Tree, src: Path, root_frame: str | None) -> str:
    frames = set(tree.parent) | set(tree.parent.values())
    if root_frame is not None:
        r = _frame_id(root_frame)
        if r not in frames:
            raise FormatError(
                src,
                f"root_frame {root_frame!r} is not a tf frame; frames are "
                f"{', '.join(sorted(frames))}",
                where="tf",
            )
        return r
    size: dict[str, int] = defaultdict(int)
    for child in tree.parent:
        size[tree.root(child)] += 1
    return min(size, key=lambda r: (-size[r], r))


def _tf_arrays(
    tree: _Tree, root: str, frame: str, t_ns: IntArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Pose of ``frame`` in ``root`` at times ``t_ns``: positions, quaternions, ok.

    Composed from their lowest common ancestor, so that a frame below ``root``
    gets exactly the composition of the transforms between them.
    """
    above = [*tree.path(root)]
    below = tree.path(frame)
    common = 0
    while common < min(len(above), len(below)) and above[common] == below[common]:
        common += 1
    base = below[common - 1] if common else None
    p, q, ok = tree.lookup(frame, t_ns, base=base)
    if len(above) > common:
        rp, rq, rok = tree.lookup(root, t_ns, base=base)
        p, q = se3.relative_pose(rp, rq, p, q)
        ok = ok & rok
    return p, q, ok


def _in_root(
    series: _Series, tree: _Tree | None, root: str | None
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Poses of a pose topic, moved into the tf root frame when their frame is in its tree."""
    p, q, ok = series.pose[:, :3], series.pose[:, 3:], series.visible
    frame = series.frame
    if tree is None or root is None or frame == root or tree.root(frame) != tree.root(root):
        return p, q, ok
    fp, fq, fok = _tf_arrays(tree, root, frame, series.stamps)
    p, q = se3.pose_compose(fp, fq, p, q)
    return p, q, ok & fok
