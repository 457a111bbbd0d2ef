"""Hand-level interaction: a hand interacts with an object when enough fingers do."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from thirdhand.arrays import IntArray
from thirdhand.demonstration import Demonstration


def finger_groups(demo: Demonstration) -> dict[str, list[str]]:
    """Fingers per hand: ``BodyInfo.hand_body`` (or ``hand``) -> finger body names."""
    groups: dict[str, list[str]] = {}
    for info in demo.bodies:
        if info.kind != "finger":
            continue
        key = info.hand_body or (f"{info.person}/{info.hand}" if info.person else info.hand)
        if key is None:
            continue
        groups.setdefault(key, []).append(info.name)
    return groups


def aggregate_hand(finger_labels: Sequence[IntArray], *, min_fingers: int = 2) -> IntArray:
    """1 where at least ``min_fingers`` of the fingers' labels are 1.

    Parameters
    ----------
    finger_labels : sequence of ndarray of int, each of shape (n_steps,)
        Per-finger labels with one object.
    min_fingers : int
        Votes needed; capped at the number of fingers, so a one-finger hand still counts.
    """
    if not finger_labels:
        raise ValueError("no finger labels to aggregate")
    votes = np.sum(np.stack([np.asarray(f) != 0 for f in finger_labels]), axis=0)
    need = max(1, min(min_fingers, len(finger_labels)))
    return (votes >= need).astype(np.int64)


def aggregate_hands(
    labels: Mapping[tuple[str, str], IntArray],
    groups: Mapping[str, Sequence[str]],
    *,
    min_fingers: int = 2,
) -> dict[tuple[str, str], IntArray]:
    """Hand–object labels from finger–object labels.

    Parameters
    ----------
    labels : mapping (finger, object) -> ndarray of int, shape (n_steps,)
    groups : mapping hand -> finger names
    min_fingers : int

    Returns
    -------
    dict (hand, object) -> ndarray of int, shape (n_steps,)
    """
    out: dict[tuple[str, str], IntArray] = {}
    objects = sorted({o for (_, o) in labels})
    for hand, fingers in groups.items():
        for obj in objects:
            per = [labels[(f, obj)] for f in fingers if (f, obj) in labels]
            if per:
                out[(hand, obj)] = aggregate_hand(per, min_fingers=min_fingers)
    return out


__all__ = ["aggregate_hand", "aggregate_hands", "finger_groups"]
