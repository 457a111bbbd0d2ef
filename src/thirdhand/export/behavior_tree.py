"""A task's plan as a BehaviorTree.CPP v4 tree (XML that Groot2 opens).

The main tree ``Assembly`` is a ``Sequence`` over the plan's steps. Each step is
one instance of the subtree ``AssemblyStep`` — ``Pick`` the child, move it
along the constraint (``MoveAlongConstraint``: to the goal pose in the
parent's frame, inside the free-DOF ranges, inserting along the free axis),
``Place`` it — with the constraint's parent, child, goal pose and free-DOF
ranges as its ports. Steps the plan leaves in any order (no step between them
in the plan's partial order, :meth:`TaskFile.predecessors`) go under a
``Parallel`` with ``success_count="-1"`` (all must succeed, in any order).
Steps are grouped into layers by their longest chain of predecessors: every
tree run respects the plan's order, and steps of one layer are unordered
(a step free with respect to a later layer is kept in its own layer, a safe
restriction of the partial order).

Port values are strings; numbers are separated by ``;`` (BehaviorTree.CPP's
``convertFromString`` for ``std::vector<double>``):

``goal_pose``
    The child's pose in the parent frame when the constraint holds:
    ``x;y;z;qx;qy;qz;qw`` (metres, unit quaternion).
``constraint_frame``
    The constraint frame in the child frame, same layout.
``free_dofs``
    ``min;max`` of tx ty tz (metres) and rx ry rz (radians) in the constraint
    frame: 12 numbers.

Names go into the XML as they are (the robot side looks objects up by name),
so a name the tree cannot hold is refused with one line
(:func:`check_port_value`): a control character (XML 1.0 has no way to write
most of them, and none belongs in an object name) and a value BehaviorTree.CPP
would read as a blackboard reference rather than a string (``{child}``: a
value whose first and last characters, spaces aside, are braces).

The ``TreeNodesModel`` declares every custom node and its ports (with
descriptions), so Groot2 shows the tree and BehaviorTree.CPP can check the
subtree's ports. The robot side implements ``Pick``, ``MoveAlongConstraint``
and ``Place`` (see ``docs/how-to/robot.md``).
"""

from __future__ import annotations

import unicodedata
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from thirdhand.errors import TaskFileError
from thirdhand.task.model import TaskFile

#: The ``BTCPP_format`` this module writes.
BTCPP_FORMAT = "4"
#: ID of the main tree.
MAIN_TREE = "Assembly"
#: ID of the subtree every step instantiates.
STEP_TREE = "AssemblyStep"

#: Ports of the step subtree: name and description.
STEP_PORTS: tuple[tuple[str, str], ...] = (
    ("step", "Index of the plan step (0-based)."),
    ("constraint", "Id of the constraint the step makes."),
    ("constraint_type", "fixed, prismatic, revolute, free, cylindrical or screw."),
    ("parent", "The object the child is attached to (already in the assembly)."),
    ("child", "The object the robot picks and attaches."),
    ("goal_pose", "Child pose in the parent frame: x;y;z;qx;qy;qz;qw (m, unit quaternion)."),
    ("constraint_frame", "Constraint frame in the child frame: x;y;z;qx;qy;qz;qw."),
    ("free_dofs", "min;max of tx ty tz (m) and rx ry rz (rad) in the constraint frame."),
)

#: The custom action nodes: ID, description, ports (name, the step port it is remapped from).
ACTIONS: tuple[tuple[str, str, tuple[tuple[str, str], ...]], ...] = (
    ("Pick", "Grasp the object where it lies.", (("object", "child"),)),
    (
        "MoveAlongConstraint",
        "Bring the held child to goal_pose in the parent frame, inserting along the free DOFs.",
        (
            ("parent", "parent"),
            ("child", "child"),
            ("constraint_type", "constraint_type"),
            ("goal_pose", "goal_pose"),
            ("constraint_frame", "constraint_frame"),
            ("free_dofs", "free_dofs"),
        ),
    ),
    (
        "Place",
        "Release the child once the constraint holds and retreat.",
        (("object", "child"), ("parent", "parent"), ("constraint", "constraint")),
    ),
)


@dataclass(frozen=True)
class StepPorts:
    """The port values of one step's subtree instance (strings, as written)."""

    index: int
    values: dict[str, str]

    @property
    def label(self) -> str:
        """The instance name: ``step 1: leg2 on seating``."""
        return f"step {self.index + 1}: {self.values['child']} on {self.values['parent']}"


def _nums(values: tuple[float, ...] | list[float]) -> str:
    return ";".join(f"{float(v):.9g}" for v in values)


def check_port_value(value: str, *, where: str) -> str:
    """``value`` if a BehaviorTree.CPP v4 XML port can hold it as a plain string.

    Raises
    ------
    TaskFileError
        A control or non-character code point (``where`` names the field), or a
        value BehaviorTree.CPP reads as a blackboard reference (``{name}``).
    """
    for ch in value:
        cat = unicodedata.category(ch)
        if cat in ("Cc", "Cs") or ch in ("\ufffe", "\uffff"):
            raise TaskFileError(
                f"{where}: {value!r} has the character U+{ord(ch):04X}, which a behaviour "
                "tree's XML cannot hold; rename it in the task file"
            )
    stripped = value.strip(" ")
    if len(stripped) >= 2 and stripped[0] == "{" and stripped[-1] == "}":
        raise TaskFileError(
            f"{where}: {value!r} would be read by BehaviorTree.CPP as a blackboard "
            "reference, not a name; rename it in the task file"
        )
    return value


def step_ports(task: TaskFile) -> list[StepPorts]:
    """Every plan step's port values.

    Raises
    ------
    TaskFileError
        No plan, a step whose constraint is not in the task, or a name a port
        cannot hold (:func:`check_port_value`).
    """
    if not task.plan:
        raise TaskFileError("the task has no plan (learn it from a demonstration first)")
    by_id = {c.id: c for c in task.constraints}
    out = []
    for i, s in enumerate(task.plan):
        c = by_id.get(s.constraint or "")
        if c is None:
            cands = [c for c in task.constraints if (c.parent, c.child) == (s.parent, s.child)]
            if len(cands) != 1:
                raise TaskFileError(
                    f"plan[{i}]: no constraint for {s.child} -> {s.parent} "
                    f"(constraint {s.constraint!r}); the tree needs its goal pose"
                )
            c = cands[0]
        frame = c.frame
        check_port_value(c.id, where=f"plan[{i}].constraint")
        check_port_value(s.parent, where=f"plan[{i}].parent")
        check_port_value(s.child, where=f"plan[{i}].child")
        out.append(
            StepPorts(
                index=i,
                values={
                    "step": str(i),
                    "constraint": c.id,
                    "constraint_type": c.type,
                    "parent": s.parent,
                    "child": s.child,
                    "goal_pose": _nums([*c.pos, *c.quat]),
                    "constraint_frame": _nums([*frame.pos, *frame.quat]),
                    "free_dofs": _nums([v for pair in c.free_dofs.ranges() for v in pair]),
                },
            )
        )
    return out


def layers(predecessors: list[list[int]]) -> list[list[int]]:
    """Steps grouped by their longest chain of predecessors (each list in plan order).

    Parameters
    ----------
    predecessors : list of list of int
        For each step the earlier steps it must follow.
    """
    depth: list[int] = []
    for preds in predecessors:
        depth.append(1 + max((depth[j] for j in preds), default=-1))
    return [[i for i, d in enumerate(depth) if d == k] for k in range(max(depth, default=-1) + 1)]


def _port(parent: ET.Element, name: str, description: str) -> None:
    el = ET.SubElement(parent, "input_port", name=name, type="std::string")
    el.text = description


def tree_xml(task: TaskFile) -> str:
    """The BehaviorTree.CPP v4 XML document of the task's plan.

    Raises
    ------
    TaskFileError
        No plan, or a step without its constraint.
    """
    steps = step_ports(task)
    root = ET.Element("root", BTCPP_format=BTCPP_FORMAT, main_tree_to_execute=MAIN_TREE)
    main = ET.SubElement(root, "BehaviorTree", ID=MAIN_TREE)
    seq = ET.SubElement(main, "Sequence", name="assembly")
    for layer in layers(task.predecessors()):
        holder = seq
        if len(layer) > 1:
            holder = ET.SubElement(
                seq, "Parallel", name="any order", success_count="-1", failure_count="1"
            )
        for i in layer:
            attrib = {"ID": STEP_TREE, "name": steps[i].label, **steps[i].values}
            ET.SubElement(holder, "SubTree", attrib)
    sub = ET.SubElement(root, "BehaviorTree", ID=STEP_TREE)
    body = ET.SubElement(sub, "Sequence", name="pick, move along the constraint, place")
    for node, _, ports in ACTIONS:
        ET.SubElement(body, node, {"name": node} | {p: f"{{{src}}}" for p, src in ports})
    model = ET.SubElement(root, "TreeNodesModel")
    desc = dict(STEP_PORTS)
    for node, text, ports in ACTIONS:
        el = ET.SubElement(model, "Action", ID=node)
        for p, src in ports:
            _port(el, p, desc[src] if p == src else f"The step's {src}: {desc[src][4:]}")
        ET.SubElement(el, "MetadataFields").append(ET.Element("Metadata", description=text))
    el = ET.SubElement(model, "SubTree", ID=STEP_TREE)
    for p, text in STEP_PORTS:
        _port(el, p, text)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
