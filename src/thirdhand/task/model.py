"""The task file ``thirdhand.task/2``: objects, constraints, plan, stage blocks, provenance.

Everything learned about one task in one versioned JSON document. The review GUI
reads and writes it; execution reads it. Validation runs on construction; the
cross-field checks (unknown object or constraint, duplicate id...) name the JSON
location of the problem, e.g. ``constraints[2].child: unknown object 'leg7'``.
The stage blocks are typed (:mod:`thirdhand.task.stages`); a ``thirdhand.task/1``
document is migrated on load (:mod:`thirdhand.task.migrate`).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import (
    AwareDatetime,
    Field,
    StringConstraints,
    ValidationError,
    field_validator,
    model_validator,
)

from thirdhand._version import __version__
from thirdhand.errors import TaskFileError
from thirdhand.readlimits import open_input
from thirdhand.task.constraint import Constraint, Name
from thirdhand.task.geometry import Pose, Positive, TaskModel, Vec3
from thirdhand.task.stages import Stages

#: The schema string of this version of the task file.
SCHEMA = "thirdhand.task/2"
#: Earlier schema strings :func:`thirdhand.task.migrate.migrate` reads.
OLD_SCHEMAS: tuple[str, ...] = ("thirdhand.task/1",)

ObjectKind = Literal["part", "tool", "finger", "hand", "head", "other"]
OBJECT_KINDS: tuple[str, ...] = get_args(ObjectKind)
Sha256 = Annotated[str, StringConstraints(pattern=r"^[0-9a-f]{64}$")]


def utc_now() -> datetime:
    """The current time, timezone-aware UTC."""
    return datetime.now(UTC)


class TaskObject(TaskModel):
    """An object of the task: a part, a tool...

    Attributes
    ----------
    name : str
        Unique; constraints and plan steps refer to it.
    kind : {"part", "tool", "finger", "hand", "head", "other"}
    mesh : str or None
        Path of the mesh file (relative paths are relative to the task file).
    scale : float or None
        Mesh units to metres (e.g. 0.001 for a mesh in millimetres).
    mesh_to_body : Pose or None
        The mesh's pose in the body frame (maps scaled mesh coordinates into the body frame).
    bbox_min, bbox_max : tuple of 3 floats or None
        The object's bounding box in its body frame, metres: the shape drawn and
        checked for collisions when no mesh is found.
    """

    name: Name
    kind: ObjectKind = "part"
    mesh: str | None = None
    scale: Positive | None = None
    mesh_to_body: Pose | None = None
    # Left out of the JSON when unset, so files of earlier versions round-trip exactly.
    bbox_min: Vec3 | None = Field(default=None, exclude_if=lambda v: v is None)
    bbox_max: Vec3 | None = Field(default=None, exclude_if=lambda v: v is None)

    @model_validator(mode="after")
    def _check_bbox(self) -> TaskObject:
        if (self.bbox_min is None) != (self.bbox_max is None):
            raise ValueError("bbox_min and bbox_max go together; give both or neither")
        if self.bbox_min is not None and self.bbox_max is not None:
            for axis, lo, hi in zip("xyz", self.bbox_min, self.bbox_max, strict=True):
                if lo > hi:
                    raise ValueError(f"bbox_min.{axis} = {lo} > bbox_max.{axis} = {hi}")
        return self


class TaskStep(TaskModel):
    """One step ``action(parent, child, symbol)`` of the assembly plan.

    Attributes
    ----------
    action : str
        The action's name, ``"action"`` for assembling ``child`` onto ``parent``.
    parent, child : str
        Object names.
    symbol : str or None
        The constraint's symbol.
    constraint : str or None
        Id of the constraint the step establishes.
    time : float or None
        Seconds on the demonstration's time axis.
    keyframe : dict of str to Pose
        Every body's pose (world frame) at that moment.
    after : list of int or None
        Partial order: indices of the steps this one must follow (each an earlier
        step). None means after the previous step (a total order).
    """

    action: Name = "action"
    parent: Name
    child: Name
    symbol: str | None = None
    constraint: str | None = None
    time: float | None = None
    keyframe: dict[str, Pose] = Field(default_factory=dict)
    after: list[int] | None = None


class InputFile(TaskModel):
    """An input the task was learned from: its path and the SHA-256 of its content."""

    path: Name
    sha256: Sha256 | None = None

    @classmethod
    def from_path(cls, path: str | os.PathLike[str]) -> InputFile:
        """Hash the file at ``path`` (a folder: every file under it, by relative path)."""
        p = Path(path)
        h = hashlib.sha256()
        files = sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
        for f in files:
            if p.is_dir():
                h.update(f.relative_to(p).as_posix().encode() + b"\0")
            with open_input(f, what="input file") as fh:
                while block := fh.read(1 << 20):
                    h.update(block)
        return cls(path=os.fspath(path), sha256=h.hexdigest())


class Correction(TaskModel):
    """What a person changed: who, when, which field (a JSON location), old and new value."""

    who: str
    when: AwareDatetime
    field: Name
    old: Any = None
    new: Any = None


class Provenance(TaskModel):
    """Where the task came from and what people changed in it."""

    inputs: list[InputFile] = Field(default_factory=list)
    thirdhand_version: str | None = None
    parameters: dict[str, Any] = Field(default_factory=dict)
    created: AwareDatetime | None = None
    modified: AwareDatetime | None = None
    corrections: list[Correction] = Field(default_factory=list)


def _plain(item: TaskModel | Mapping[str, Any]) -> Any:
    """A model as plain data, so the new task owns fresh copies (and validates them)."""
    return item.model_dump(by_alias=True) if isinstance(item, TaskModel) else item


def _duplicates(names: Iterable[str]) -> list[tuple[int, str]]:
    seen: set[str] = set()
    out = []
    for i, n in enumerate(names):
        if n in seen:
            out.append((i, n))
        seen.add(n)
    return out


def _tree_problem(constraints: Sequence[Any]) -> str | None:
    """The first way the constraints' parent links fail to form a forest, or None.

    Each object has at most one parent (several constraints between the same
    pair, e.g. over time, are fine) and following parents never comes back.
    """
    parent_of: dict[str, tuple[str, int]] = {}
    for i, c in enumerate(constraints):
        first = parent_of.setdefault(c.child, (c.parent, i))
        if first[0] != c.parent:
            return (
                f"constraints[{i}].parent: {c.child!r} already has the parent {first[0]!r} "
                f"(constraints[{first[1]}]); an object has one parent, got also {c.parent!r}"
            )
    for start in parent_of:
        seen = [start]
        node = start
        while node in parent_of:
            node, i = parent_of[node]
            if node == start:
                cycle = " -> ".join([*seen, start])
                return f"constraints[{i}]: the parents form a cycle ({cycle})"
            if node in seen:
                break
            seen.append(node)
    return None


#: Object kinds a plan never attaches nor attaches to: a person's body parts. (A
#: tool is an object of the assembly: a screwdriver engages a screw.)
BODY_PART_KINDS: frozenset[str] = frozenset({"finger", "hand", "head"})


def _step_problem(
    i: int, s: TaskStep, c: Constraint | None, kinds: Mapping[str, str], mounted: Mapping[str, int]
) -> str | None:
    """How plan step ``i`` contradicts its constraint or its objects, or None.

    The step must attach what its constraint attaches (same parent, same child),
    attach no object to itself, attach each object once, and attach objects,
    not the person's body parts.
    """
    if s.parent == s.child:
        return (
            f"plan[{i}]: parent and child are both {s.parent!r} (a part is not mounted on itself)"
        )
    if c is not None and (s.parent, s.child) != (c.parent, c.child):
        return (
            f"plan[{i}]: mounts {s.child!r} on {s.parent!r}, but its constraint {c.id!r} "
            f"mounts {c.child!r} on {c.parent!r}"
        )
    if s.child in mounted:
        return f"plan[{i}].child: {s.child!r} is already mounted by plan[{mounted[s.child]}]"
    for role in ("child", "parent"):
        name = getattr(s, role)
        if kinds.get(name) in BODY_PART_KINDS:
            return (
                f"plan[{i}].{role}: {name!r} is a {kinds[name]} of the person, "
                "not an object of the assembly"
            )
    return None


class TaskFile(TaskModel):
    """Everything learned about one task (schema ``thirdhand.task/2``).

    Attributes
    ----------
    schema_ : str
        Always ``"thirdhand.task/2"`` (JSON key ``schema``).
    objects : list of TaskObject
    constraints : list of Constraint
    plan : list of TaskStep
        Ordered steps.
    stages : Stages
        A typed block per pipeline stage (``constraints``, ``plan``,
        ``primitives``, ``reward``, ``review``, ``perception``, ``scene``,
        ``grasps``, ``execution``); blocks this version does not know are kept.
    provenance : Provenance
    """

    schema_: str = Field(alias="schema")
    objects: list[TaskObject] = Field(default_factory=list)
    constraints: list[Constraint] = Field(default_factory=list)
    plan: list[TaskStep] = Field(default_factory=list)
    stages: Stages = Field(default_factory=Stages)
    provenance: Provenance = Field(default_factory=Provenance)

    @field_validator("schema_", mode="before")
    @classmethod
    def _check_schema(cls, value: Any) -> Any:
        if value != SCHEMA:
            got = f'"{value}"' if isinstance(value, str) else repr(value)
            hint = " (load_task and parse_task migrate it)" if value in OLD_SCHEMAS else ""
            raise ValueError(f'expected "{SCHEMA}", got {got}{hint}')
        return value

    @model_validator(mode="after")
    def _check_references(self) -> TaskFile:
        problem = self._first_reference_problem()
        if problem is not None:
            raise ValueError(problem)
        return self

    def _first_reference_problem(self) -> str | None:
        for i, name in _duplicates(o.name for o in self.objects):
            return f"objects[{i}].name: duplicate object name {name!r}"
        for i, cid in _duplicates(c.id for c in self.constraints):
            return f"constraints[{i}].id: duplicate constraint id {cid!r}"
        names = {o.name for o in self.objects}
        for i, c in enumerate(self.constraints):
            for role in ("parent", "child"):
                if getattr(c, role) not in names:
                    return f"constraints[{i}].{role}: unknown object {getattr(c, role)!r}"
            if c.parent == c.child:
                return f"constraints[{i}]: parent and child are both {c.parent!r}"
        tree_problem = _tree_problem(self.constraints)
        if tree_problem is not None:
            return tree_problem
        by_id = {c.id: c for c in self.constraints}
        kinds = {o.name: o.kind for o in self.objects}
        made: dict[str, int] = {}
        mounted: dict[str, int] = {}
        for i, s in enumerate(self.plan):
            for role in ("parent", "child"):
                if getattr(s, role) not in names:
                    return f"plan[{i}].{role}: unknown object {getattr(s, role)!r}"
            if s.constraint is not None and s.constraint not in by_id:
                return f"plan[{i}].constraint: unknown constraint {s.constraint!r}"
            if s.constraint is not None and s.constraint in made:
                return (
                    f"plan[{i}].constraint: constraint {s.constraint!r} is already made by "
                    f"plan[{made[s.constraint]}] (a plan makes each constraint once)"
                )
            if s.constraint is not None:
                made[s.constraint] = i
            problem = _step_problem(i, s, by_id.get(s.constraint or ""), kinds, mounted)
            if problem is not None:
                return problem
            mounted[s.child] = i
            for k, j in enumerate(s.after or []):
                if not 0 <= j < i:
                    return (
                        f"plan[{i}].after[{k}]: step {j} is not an earlier step "
                        f"(expected an index in 0..{i - 1})"
                    )
        return None

    @classmethod
    def new(
        cls,
        *,
        objects: Sequence[TaskObject | Mapping[str, Any]] = (),
        constraints: Sequence[Constraint | Mapping[str, Any]] = (),
        plan: Sequence[TaskStep | Mapping[str, Any]] = (),
        stages: Stages | Mapping[str, Any] | None = None,
        inputs: Sequence[InputFile | str | os.PathLike[str]] = (),
        parameters: Mapping[str, Any] | None = None,
    ) -> TaskFile:
        """A new task with provenance filled in: version, created = modified = now.

        ``inputs`` given as paths are hashed (:meth:`InputFile.from_path`).

        Raises
        ------
        TaskFileError
            If the content is invalid (first error, with its location).
        """
        now = utc_now()
        files = [i if isinstance(i, InputFile) else InputFile.from_path(i) for i in inputs]
        try:
            return cls.model_validate(
                {
                    "schema": SCHEMA,
                    "objects": [_plain(o) for o in objects],
                    "constraints": [_plain(c) for c in constraints],
                    "plan": [_plain(p) for p in plan],
                    "stages": _plain(stages) if isinstance(stages, Stages) else dict(stages or {}),
                    "provenance": Provenance(
                        inputs=files,
                        thirdhand_version=__version__,
                        parameters=dict(parameters or {}),
                        created=now,
                        modified=now,
                    ),
                }
            )
        except ValidationError as exc:
            from thirdhand.task.errors import first_error

            raise TaskFileError(f"new task: {first_error(exc)}") from None

    def objects_by_name(self) -> dict[str, TaskObject]:
        """The objects keyed by name."""
        return {o.name: o for o in self.objects}

    def constraint_by_id(self, id: str) -> Constraint:
        """The constraint with this id.

        Raises
        ------
        KeyError
            If there is none.
        """
        for c in self.constraints:
            if c.id == id:
                return c
        raise KeyError(f"no constraint with id {id!r}; ids are {[c.id for c in self.constraints]}")

    def foreign_recording_problem(self, body_names: Iterable[str]) -> str | None:
        """Why a recording with these bodies is not one of this task, or None.

        A recording of the task shows some of its objects; one that shows none is a
        recording of another task (a task without objects takes any).
        """
        if self.objects and not {o.name for o in self.objects} & set(body_names):
            names = sorted(o.name for o in self.objects)
            more = ", …" if len(names) > 5 else ""
            return (
                f"shows none of the task's objects ({', '.join(names[:5])}{more}); "
                "give a recording of this task"
            )
        return None

    def predecessors(self) -> list[list[int]]:
        """For each plan step, the indices of the steps it must follow.

        Those of ``after`` when given, else the previous step.
        """
        return [
            list(s.after) if s.after is not None else ([i - 1] if i else [])
            for i, s in enumerate(self.plan)
        ]

    def record_correction(
        self, *, who: str, field: str, old: Any, new: Any, when: datetime | None = None
    ) -> Correction:
        """Append a person's change to the provenance and set ``modified``.

        The change itself is made by the caller; ``field`` is its JSON location
        (``"constraints[2].free_dofs.rz"``), ``old`` and ``new`` JSON-able values.
        """
        c = Correction(who=who, when=when or utc_now(), field=field, old=old, new=new)
        self.provenance.corrections.append(c)
        self.provenance.modified = c.when
        return c

    def to_json_dict(self) -> dict[str, Any]:
        """The JSON document as plain Python data (declared fields first, unknown ones after)."""
        data: dict[str, Any] = self.model_dump(mode="json", by_alias=True)
        return data
