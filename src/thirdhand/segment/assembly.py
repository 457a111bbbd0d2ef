"""Part–part labels closed over the assembly: interaction through parts in contact.

Two parts interact while the assembly's established joints connect them and
their relative pose is constant. A pair-wise model sees this directly only for
parts that touch: a screw driven into a board, a leg in the seat. Two screws on
opposite boards of a toolbox, 36 cm apart, interact through the boards; while
the whole toolbox rests on the table their two trajectories say nothing (both
are still whether joined or not), and the CRF can only guess from history.

The closure decides such pairs from the touching ones. Per latent step, the
graph over the parts has an edge for every part–part pair (:data:`CLOSED_KINDS`)
that the CRF labels interacting **and** whose bounding boxes are within
``contact_max_m`` of each other; a pair whose boxes are farther apart is
labelled by whether that graph connects its two parts. Tool–part pairs keep the
CRF's labels: closed too, a board held against the toolbox front before its
screws are tight (touching, moving with it, not joined) made the screwdriver
"interact" with the front (held-out toolbox tool–part F1 0.998 → 0.83), while
the CRF alone sees a screwdriver resting in a screw move with the screw's board.
Connection through edges that are each rigid implies a rigid pair, so the
closure keeps the definition.

Pairs with a body without a bounding box (no geometry: a real recording without
meshes) cannot be told touching from apart: they keep their own label and are
edges of the graph whenever that label is 1.

The graph changes only at a few steps, so connectivity is computed once per
distinct edge set (``numpy.unique`` over the steps' edge rows, then
``scipy.sparse.csgraph.connected_components``), ``O(n_distinct × n_pairs)``,
and only over the steps at which some pair is apart (none without geometry).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from thirdhand.arrays import BoolArray, FloatArray, IntArray
from thirdhand.segment.features import SegmentationError

#: Pair kinds (:func:`thirdhand.segment.pipeline.pair_kind`) the closure labels.
CLOSED_KINDS = ("part-part",)


@dataclass(frozen=True)
class ClosureConfig:
    """How part–part labels are closed over the assembly; stored with the model.

    Attributes
    ----------
    contact_max_m : float
        Bounding-box gap, metres, up to which two parts count as touching: their
        own label is kept and, when 1, joins them in the graph.
    """

    contact_max_m: float = 0.01

    def __post_init__(self) -> None:
        if not (np.isfinite(self.contact_max_m) and self.contact_max_m >= 0.0):
            raise SegmentationError(
                f"closure contact_max_m must be a finite distance >= 0 m, got {self.contact_max_m}"
            )

    def to_dict(self) -> dict[str, float]:
        """JSON-able form."""
        return asdict(self)


def touching(gap: FloatArray | None, config: ClosureConfig) -> BoolArray | None:
    """Steps at which a pair's bounding boxes touch, or None when the pair has no boxes.

    Parameters
    ----------
    gap : ndarray, shape (n_steps,), metres, or None
        Bounding-box gap per latent step (NaN: unknown, taken as apart).
    config : ClosureConfig
    """
    if gap is None:
        return None
    g = np.asarray(gap, dtype=np.float64)
    return np.nan_to_num(g, nan=np.inf) <= config.contact_max_m


def close_pairs(
    pairs: Sequence[tuple[str, str]],
    labels: Sequence[IntArray],
    touch: Sequence[BoolArray | None],
) -> list[IntArray]:
    """Labels of part–part pairs closed over the touching, interacting ones.

    Parameters
    ----------
    pairs : sequence of (a, b)
        The part–part pairs, ``P`` of them.
    labels : sequence of ndarray of int, each shape (n_steps,)
        The CRF's labels of each pair.
    touch : sequence of (ndarray of bool, shape (n_steps,)) or None
        Whether the pair's boxes touch at each step (:func:`touching`); None for a
        pair without boxes, which keeps its label and is an edge wherever it is 1.

    Returns
    -------
    list of ndarray of int, each shape (n_steps,)
        The pair's own label where its boxes touch (or it has none), else 1 exactly
        when the graph of touching interacting pairs connects its two parts.
    """
    if not (len(pairs) == len(labels) == len(touch)):
        raise SegmentationError(
            f"closure needs one label and one contact row per pair, got {len(pairs)} pairs, "
            f"{len(labels)} labels, {len(touch)} contact rows"
        )
    if not pairs:
        return []
    n_steps = len(labels[0])
    lab = np.zeros((len(pairs), n_steps), dtype=bool)
    near = np.ones((len(pairs), n_steps), dtype=bool)
    for k, (y, c) in enumerate(zip(labels, touch, strict=True)):
        if len(y) != n_steps or (c is not None and len(c) != n_steps):
            raise SegmentationError(
                f"closure: pair {pairs[k]} has {len(y)} labels, expected {n_steps} steps"
            )
        lab[k] = np.asarray(y) != 0
        if c is not None:
            near[k] = c
    edges = lab & near
    out = lab.copy()
    # Only steps where some pair is apart need the graph (none without geometry).
    steps = np.flatnonzero((~near).any(axis=0))
    if len(steps):
        names = sorted({n for p in pairs for n in p})
        index = {n: i for i, n in enumerate(names)}
        ia = np.array([index[a] for a, _ in pairs])
        ib = np.array([index[b] for _, b in pairs])
        distinct, which = np.unique(edges[:, steps].T, axis=0, return_inverse=True)
        joined = np.empty((len(distinct), len(pairs)), dtype=bool)
        for u, row in enumerate(distinct):
            sel = np.flatnonzero(row)
            graph = csr_matrix(
                (np.ones(len(sel)), (ia[sel], ib[sel])), shape=(len(names), len(names))
            )
            _, comp = connected_components(graph, directed=False)
            joined[u] = comp[ia] == comp[ib]
        sub = out[:, steps]
        apart = ~near[:, steps]
        sub[apart] = joined[np.asarray(which).ravel()].T[apart]
        out[:, steps] = sub
    return [row.astype(np.int64) for row in out]


__all__ = ["CLOSED_KINDS", "ClosureConfig", "close_pairs", "touching"]
