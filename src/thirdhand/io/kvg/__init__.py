"""The MLR key-value graph syntax (``.kvg``) and the 3rdHand annotation files written in it.

A graph is a sequence of nodes. A node is a list of keys (bare words or quoted
strings), optionally parents in parentheses, and optionally a value::

    agents {                                        # keys ["agents"], value: a subgraph
      /human/rh/thumb = { type = digit, rn = 0 }    # keys ["/human/rh/thumb"], value: a subgraph
    }
    TS /human/rh /toolbox/side_front { lock { from=2392 to=2505 } }

A value after ``=`` is a number, ``true``/``false``, a bare word or quoted string, a
``[ ... ]`` array of numbers, or a ``{ ... }`` subgraph; a ``{ ... }`` right after
the keys is a subgraph too. Nodes are separated by newlines, commas or
semicolons; ``#`` starts a comment.

Annotation files (``ann_kvg.kvg``) hold one node per labelled body pair:

- ``TS hand object { lock { from=F to=T } ... }``: the hand touches the object
  over frames ``F..T`` (hand-object interaction phases);
- ``CE parent child { lock { from=F to=T } ... }``: a constraint between two
  objects holds over frames ``F..T``; ``F`` is its onset.

Frames are 0-based indices into ``poses.dat``'s blocks (the toolbox_3 labels of a
22,548-frame recording end at frame 22547). The file does not say which kind of
constraint a ``CE`` is: it reads as ``type="fixed"`` (the toolbox sides are
screwed together). A ``CE`` lock ending before the last frame of the recording
also yields a removal event at ``T``. thirdhand writes extra keys inside a lock
only when a label carries more than the original syntax holds (``type``,
``symbol``, ``pos``, ``quat``, ``free_dofs``), and ``PS parent child { step {
frame=F symbol=S } }`` nodes for plan steps, so that labels round-trip.

Modules
-------
:mod:`~thirdhand.io.kvg.graph` (``Node``, ``Graph``), :mod:`~thirdhand.io.kvg.syntax`
(``parse``, ``read``, ``format_value``), :mod:`~thirdhand.io.kvg.annotations`
(``Annotation``, ``parse_annotations``), :mod:`~thirdhand.io.kvg.labels`
(``read_annotations``, ``annotations_to_labels``) and :mod:`~thirdhand.io.kvg.writer`
(``format_annotations``).
"""

from thirdhand.io.kvg.annotations import TAGS, Annotation, last_span_end, parse_annotations
from thirdhand.io.kvg.graph import Graph, Node
from thirdhand.io.kvg.graph import Value as Value
from thirdhand.io.kvg.labels import (
    annotations_to_labels,
    frame_converter,
    read_annotations,
    resolve_body,
)
from thirdhand.io.kvg.syntax import format_value, parse, read
from thirdhand.io.kvg.writer import format_annotations, nearest_frames

__all__ = [
    "TAGS",
    "Annotation",
    "Graph",
    "Node",
    "annotations_to_labels",
    "format_annotations",
    "format_value",
    "frame_converter",
    "last_span_end",
    "nearest_frames",
    "parse",
    "parse_annotations",
    "read",
    "read_annotations",
    "resolve_body",
]
