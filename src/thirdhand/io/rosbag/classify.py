"""Message-type classification: what a topic carries, judged by its type's fields."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from thirdhand.io.rosbag.constants import META_TOPIC

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore


_INT_TYPES = frozenset({"int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"})


@dataclass(frozen=True)
class _Spec:
    """How to pull poses out of one topic's messages.

    ``pose_path`` leads from the message (pose topics) or from the object's
    ``holder`` field (world-model topics) to a ``geometry_msgs/Pose``.
    """

    kind: Literal["pose", "tf", "transform", "world", "meta"]
    pose_path: tuple[str, ...] = ()
    array: str = ""
    holder: str = ""
    visible: str | None = None


def _fields(store: Typestore, typ: str | None) -> dict[str, Any]:
    if typ is None or typ not in store.fielddefs:
        return {}
    return dict(store.fielddefs[typ][1])


def _name_of(desc: Any) -> str | None:
    """The message type of a field holding one message, else None."""
    from rosbags.interfaces import Nodetype

    return str(desc[1]) if desc is not None and desc[0] == Nodetype.NAME else None


def _element_of(desc: Any) -> str | None:
    """The message type of the elements of an array field, else None."""
    from rosbags.interfaces import Nodetype

    if desc is None or desc[0] not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return None
    return _name_of(desc[1][0])


def _base_of(desc: Any) -> str | None:
    """The primitive type of a scalar field (``uint32``, ``bool``...), else None."""
    from rosbags.interfaces import Nodetype

    return str(desc[1][0]) if desc is not None and desc[0] == Nodetype.BASE else None


def _has(store: Typestore, typ: str | None, names: Sequence[str]) -> bool:
    f = _fields(store, typ)
    return bool(f) and all(n in f for n in names)


def _pose_path(store: Typestore, typ: str, depth: int = 2) -> tuple[str, ...] | None:
    """Attributes leading from a message of type ``typ`` to a Pose, or None."""
    f = _fields(store, typ)
    if _has(store, _name_of(f.get("position")), "xyz") and _has(
        store, _name_of(f.get("orientation")), "xyzw"
    ):
        return ()
    sub = _name_of(f.get("pose"))
    if depth == 0 or sub is None:
        return None
    rest = _pose_path(store, sub, depth - 1)
    return None if rest is None else ("pose", *rest)


def _is_transform_stamped(store: Typestore, typ: str | None) -> bool:
    f = _fields(store, typ)
    return (
        _base_of(f.get("child_frame_id")) == "string"
        and "header" in f
        and _has(store, _name_of(f.get("transform")), ("translation", "rotation"))
    )


def _classify(store: Typestore, topic: str, typ: str) -> _Spec | None:
    """What a topic of message type ``typ`` carries, judged by the type's fields."""
    f = _fields(store, typ)
    if topic == META_TOPIC and _base_of(f.get("data")) == "string":
        return _Spec("meta")
    if _is_transform_stamped(store, typ):
        return _Spec("transform")
    if _is_transform_stamped(store, _element_of(f.get("transforms"))):
        return _Spec("tf")
    path = _pose_path(store, typ)
    if path is not None:
        return _Spec("pose", pose_path=path)
    for array, desc in f.items():
        ef = _fields(store, _element_of(desc))
        if _base_of(ef.get("id")) not in _INT_TYPES:
            continue
        for holder, hdesc in ef.items():
            sub = _name_of(hdesc)
            hpath = None if sub is None else _pose_path(store, sub, 1)
            if hpath is None:
                continue
            visible = next(
                (n for n, d in ef.items() if _base_of(d) == "bool" and "visible" in n.lower()),
                None,
            )
            return _Spec("world", pose_path=hpath, array=array, holder=holder, visible=visible)
    return None
