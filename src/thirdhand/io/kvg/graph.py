"""Key-value graphs: values, nodes and graphs."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Union

Value = Union[None, bool, int, float, str, tuple[float, ...], "Graph"]


@dataclass(frozen=True)
class Node:
    """One node of a key-value graph.

    Attributes
    ----------
    keys : tuple of str
    parents : tuple of str
        Names in parentheses after the keys (rare in MLR files).
    value : None, bool, int, float, str, tuple of float or Graph
        None for a node with keys only.
    line : int
        1-based line of the node's first token.
    """

    keys: tuple[str, ...]
    parents: tuple[str, ...]
    value: Value
    line: int


@dataclass(frozen=True)
class Graph:
    """A parsed key-value graph: its nodes in file order."""

    nodes: tuple[Node, ...]

    def __iter__(self) -> Iterator[Node]:
        return iter(self.nodes)

    def __len__(self) -> int:
        return len(self.nodes)

    def find(self, key: str) -> Node | None:
        """The first node whose first key is ``key``, or None."""
        return next((n for n in self.nodes if n.keys and n.keys[0] == key), None)

    def get(self, key: str, default: Value = None) -> Value:
        """Value of the first node whose first key is ``key``."""
        node = self.find(key)
        return default if node is None else node.value

    def to_dict(self) -> dict[str, object]:
        """Scalar and array entries keyed by their first key (subgraphs as nested dicts)."""
        out: dict[str, object] = {}
        for n in self.nodes:
            if n.keys:
                out[n.keys[0]] = n.value.to_dict() if isinstance(n.value, Graph) else n.value
        return out
