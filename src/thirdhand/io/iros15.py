"""The IROS 2015 user study of the 3rdHand correction GUI (``iros15_user_study.yaml``).

"Robot programming from demonstration, feedback and transfer": subjects taught
the robot a chair (``blue_chair``) and a bench (``green_bench``), then corrected
what it had learned in a GUI. The YAML nests

``subject -> scene -> session (condition A/B/C/D, or test) -> attempt ("0", "1"...)``

A session holds the learned ``plan`` (steps ``[symbol, parent, child]`` and
``wait``) and the learned constraint rows ``symbols``; some also the raw
learner output (``raw_plan`` with steps ``[action, symbol, parent, child]``,
``raw_symbols``, ``raw_error``). Each attempt holds what the subject made of it:
``corrected_plan``, ``corrected_st`` (constraint rows), ``corrected_precision``
against the reference constraints, GUI ``effort`` counts per object, and the
times the task was loaded and written.

Constraint rows (19 numbers, or 7 when every DOF is locked) become
:class:`thirdhand.taskfile.Constraint` with parent and child taken from the plan
step that uses the symbol; rows of symbols no step uses keep their raw numbers
(their child is unknown).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from thirdhand.errors import FormatError, TaskFileError, ThirdhandError
from thirdhand.task.constraint import Constraint
from thirdhand.task.model import InputFile, TaskFile, TaskObject, TaskStep

WAIT: Literal["wait"] = "wait"


@dataclass(frozen=True)
class StudyStep:
    """One plan step: ``child`` assembled onto ``parent`` with the constraint ``symbol``.

    ``action`` is the learner's action name in a raw plan (``"action1"``), else None.
    """

    symbol: str
    parent: str
    child: str
    action: str | None = None


StudyPlan = tuple[StudyStep | Literal["wait"], ...]


@dataclass(frozen=True)
class Precision:
    """Errors of constraints against the reference constraints, one entry per compared constraint.

    Attributes
    ----------
    position : tuple of float
        Position errors, metres.
    orientation : tuple of float
        Orientation errors, radians.
    reference_id : tuple of str or None
        The reference constraint (``c0``... ``c4``) each was compared with.
    object : tuple of str or None
        Objects of the learner's raw output (only in ``raw_error``; not aligned
        with the other entries: it can be shorter).
    """

    position: tuple[float, ...]
    orientation: tuple[float, ...]
    reference_id: tuple[str, ...] | None = None
    object: tuple[str, ...] | None = None

    @property
    def mean_position(self) -> float:
        """Mean position error, metres (NaN when empty)."""
        return sum(self.position) / len(self.position) if self.position else float("nan")

    @property
    def mean_orientation(self) -> float:
        """Mean orientation error, radians (NaN when empty)."""
        return sum(self.orientation) / len(self.orientation) if self.orientation else float("nan")


@dataclass(frozen=True)
class ConstraintTable:
    """Constraint rows keyed by symbol.

    Attributes
    ----------
    constraints : dict of str to Constraint
        Rows of symbols a plan step uses, with that step's parent and child.
    unused : dict of str to tuple of float
        Rows (19 or 7 numbers, as read) of symbols no plan step uses.
    """

    constraints: dict[str, Constraint] = field(default_factory=dict)
    unused: dict[str, tuple[float, ...]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.constraints) + len(self.unused)


@dataclass(frozen=True)
class Attempt:
    """One correction attempt of a session.

    Attributes
    ----------
    index : int
    state : str or None
        ``success``, ``aborted``, ``fallen``, or None when not recorded.
    corrected_plan : StudyPlan or None
    corrected_st : ConstraintTable
    corrected_precision : Precision or None
    effort : dict of str to dict of str to int
        Per object (and ``actions``), counts of GUI operations (click, movex,
        rotz, parent, reordering, kfviews...).
    loadings, writings : tuple of float
        Unix times the task was loaded into and written from the GUI, seconds.
    extra : dict
        Keys this reader does not know, as read.
    """

    index: int
    state: str | None = None
    corrected_plan: StudyPlan | None = None
    corrected_st: ConstraintTable = field(default_factory=ConstraintTable)
    corrected_precision: Precision | None = None
    effort: dict[str, dict[str, int]] = field(default_factory=dict)
    loadings: tuple[float, ...] = ()
    writings: tuple[float, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    def effort_totals(self) -> dict[str, int]:
        """Counts of each GUI operation summed over the objects."""
        out: dict[str, int] = {}
        for ops in self.effort.values():
            for op, n in ops.items():
                out[op] = out.get(op, 0) + n
        return out


@dataclass(frozen=True)
class Session:
    """What was learned in one condition of a scene, and the attempts to correct it.

    Attributes
    ----------
    name : str
        The condition (``A``, ``B``, ``C``, ``D``, ``test``).
    num_attempts : int
        As recorded (the ``test`` sessions say 0 and still hold one attempt).
    plan : StudyPlan or None
        The learned plan.
    symbols : ConstraintTable
        The learned constraints.
    raw_plan : StudyPlan or None
        The learner's raw output, before the study's pre-processing.
    raw_symbols : ConstraintTable
    raw_error : Precision or None
    attempts : tuple of Attempt
        In index order.
    extra : dict
    """

    name: str
    num_attempts: int
    plan: StudyPlan | None = None
    symbols: ConstraintTable = field(default_factory=ConstraintTable)
    raw_plan: StudyPlan | None = None
    raw_symbols: ConstraintTable = field(default_factory=ConstraintTable)
    raw_error: Precision | None = None
    attempts: tuple[Attempt, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class UserStudy:
    """The whole study: ``subjects[name][scene][session]`` is a :class:`Session`."""

    path: str
    subjects: dict[str, dict[str, dict[str, Session]]]

    def sessions(self) -> Iterator[tuple[str, str, Session]]:
        """Every ``(subject, scene, session)``, in file order."""
        for subject, scenes in self.subjects.items():
            for scene, sessions in scenes.items():
                for session in sessions.values():
                    yield subject, scene, session

    def attempts(self) -> Iterator[tuple[str, str, Session, Attempt]]:
        """Every ``(subject, scene, session, attempt)``, in file order."""
        for subject, scene, session in self.sessions():
            for attempt in session.attempts:
                yield subject, scene, session, attempt


class _Reader:
    """Converts the parsed YAML, naming ``subject/scene/session/...`` in every error."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, where: list[str], message: str) -> FormatError:
        return FormatError(self.path, message, where="/".join(where))

    def mapping(self, value: Any, where: list[str]) -> dict[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail(where, f"expected a mapping, got {type(value).__name__}")
        return {str(k): v for k, v in value.items()}

    def numbers(self, value: Any, where: list[str]) -> tuple[float, ...]:
        if not isinstance(value, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value
        ):
            raise self.fail(where, f"expected a list of numbers, got {value!r}")
        return tuple(float(v) for v in value)

    def names(self, value: Any, where: list[str]) -> tuple[str, ...]:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.fail(where, f"expected a list of names, got {value!r}")
        return tuple(value)

    def plan(self, value: Any, where: list[str], *, raw: bool) -> StudyPlan:
        if not isinstance(value, list):
            raise self.fail(where, f"expected a list of plan steps, got {type(value).__name__}")
        width = 4 if raw else 3
        steps: list[StudyStep | Literal["wait"]] = []
        for i, step in enumerate(value):
            if step == WAIT:
                steps.append(WAIT)
            elif (
                isinstance(step, list)
                and len(step) == width
                and all(isinstance(s, str) for s in step)
            ):
                steps.append(
                    StudyStep(step[-3], step[-2], step[-1], action=step[0] if raw else None)
                )
            else:
                form = "[action, symbol, parent, child]" if raw else "[symbol, parent, child]"
                raise self.fail([*where, str(i)], f"expected {form} or 'wait', got {step!r}")
        return tuple(steps)

    def table(
        self,
        value: Any,
        plan: StudyPlan | None,
        where: list[str],
        *,
        source: Literal["learned", "corrected"] = "learned",
    ) -> ConstraintTable:
        rows = self.mapping(value, where)
        users = {s.symbol: s for s in plan or () if isinstance(s, StudyStep)}
        constraints: dict[str, Constraint] = {}
        unused: dict[str, tuple[float, ...]] = {}
        for symbol, row in rows.items():
            numbers = self.numbers(row, [*where, symbol])
            step = users.get(symbol)
            if step is None:
                if len(numbers) not in (7, 19):
                    raise self.fail(
                        [*where, symbol], f"expected 19 or 7 numbers, got {len(numbers)}"
                    )
                unused[symbol] = numbers
                continue
            try:
                constraints[symbol] = Constraint.from_row(
                    row, parent=step.parent, child=step.child, symbol=symbol, source=source
                )
            except TaskFileError as exc:
                raise self.fail([*where, symbol], str(exc)) from None
        return ConstraintTable(constraints, unused)

    def precision(self, value: Any, where: list[str]) -> Precision:
        d = self.mapping(value, where)
        position = self.numbers(d.get("position"), [*where, "position"])
        orientation = self.numbers(d.get("orientation"), [*where, "orientation"])
        ids = (
            self.names(d["reference_id"], [*where, "reference_id"]) if "reference_id" in d else None
        )
        objs = self.names(d["object"], [*where, "object"]) if "object" in d else None
        for name, seq in (("orientation", orientation), ("reference_id", ids)):
            if seq is not None and len(seq) != len(position):
                raise self.fail(
                    [*where, name],
                    f"expected {len(position)} entries like position, got {len(seq)}",
                )
        return Precision(position, orientation, ids, objs)

    def effort(self, value: Any, where: list[str]) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for obj, ops in self.mapping(value, where).items():
            counts = self.mapping(ops, [*where, obj])
            for op, n in counts.items():
                if isinstance(n, bool) or not isinstance(n, int) or n < 0:
                    raise self.fail([*where, obj, op], f"expected a count, got {n!r}")
            out[obj] = counts
        return out

    def attempt(self, index: int, value: Any, where: list[str]) -> Attempt:
        d = self.mapping(value, where)
        plan = (
            self.plan(d.pop("corrected_plan"), [*where, "corrected_plan"], raw=False)
            if "corrected_plan" in d
            else None
        )
        st = d.pop("corrected_st", None)
        prec = d.pop("corrected_precision", None)
        state = d.pop("state", None)
        if state is not None and not isinstance(state, str):
            raise self.fail([*where, "state"], f"expected a name, got {state!r}")
        return Attempt(
            index=index,
            state=state,
            corrected_plan=plan,
            corrected_st=self.table(st, plan, [*where, "corrected_st"], source="corrected")
            if st is not None
            else ConstraintTable(),
            corrected_precision=self.precision(prec, [*where, "corrected_precision"])
            if prec is not None
            else None,
            effort=self.effort(d.pop("effort", {}), [*where, "effort"]),
            loadings=self.numbers(d.pop("loadings", []), [*where, "loadings"]),
            writings=self.numbers(d.pop("writings", []), [*where, "writings"]),
            extra=d,
        )

    def session(self, name: str, value: Any, where: list[str]) -> Session:
        d = self.mapping(value, where)
        n = d.pop("num_attempts", None)
        if isinstance(n, bool) or not isinstance(n, int):
            raise self.fail([*where, "num_attempts"], f"expected an integer, got {n!r}")
        plan = self.plan(d.pop("plan"), [*where, "plan"], raw=False) if "plan" in d else None
        raw_plan = (
            self.plan(d.pop("raw_plan"), [*where, "raw_plan"], raw=True)
            if "raw_plan" in d
            else None
        )
        symbols = d.pop("symbols", None)
        raw_symbols = d.pop("raw_symbols", None)
        raw_error = d.pop("raw_error", None)
        indices = sorted(int(k) for k in d if k.isdigit())
        attempts = tuple(self.attempt(i, d.pop(str(i)), [*where, str(i)]) for i in indices)
        return Session(
            name=name,
            num_attempts=n,
            plan=plan,
            symbols=self.table(symbols, plan, [*where, "symbols"])
            if symbols is not None
            else ConstraintTable(),
            raw_plan=raw_plan,
            raw_symbols=self.table(raw_symbols, raw_plan, [*where, "raw_symbols"])
            if raw_symbols is not None
            else ConstraintTable(),
            raw_error=self.precision(raw_error, [*where, "raw_error"])
            if raw_error is not None
            else None,
            attempts=attempts,
            extra=d,
        )

    def study(self, data: Any) -> UserStudy:
        subjects: dict[str, dict[str, dict[str, Session]]] = {}
        for subject, scenes in self.mapping(data, []).items():
            subjects[subject] = {}
            for scene, sessions in self.mapping(scenes, [subject]).items():
                subjects[subject][scene] = {
                    name: self.session(name, value, [subject, scene, name])
                    for name, value in self.mapping(sessions, [subject, scene]).items()
                }
        return UserStudy(os.fspath(self.path), subjects)


def read_user_study(path: str | os.PathLike[str]) -> UserStudy:
    """Read ``iros15_user_study.yaml`` into typed sessions, attempts and constraints.

    Raises
    ------
    FormatError
        If the file is not YAML (with the line), or an entry does not have the
        expected form (naming ``subject/scene/session/...``).
    """
    p = Path(path)
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    from thirdhand.readlimits import read_text_input

    text = read_text_input(p, what="user-study YAML file")
    try:
        data = yaml.load(text, Loader=loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        raise FormatError(p, f"not valid YAML: {getattr(exc, 'problem', exc)}", line=line) from None
    return _Reader(p).study(data)


def session_task(
    study: UserStudy,
    *,
    subject: str,
    scene: str,
    session: str,
    attempt: int | None = None,
    objects: Mapping[str, TaskObject] | None = None,
) -> TaskFile:
    """A task file of what was learned in a session, or of what a subject corrected.

    Parameters
    ----------
    study : UserStudy
    subject, scene, session : str
        E.g. ``"adele"``, ``"blue_chair"``, ``"A"``.
    attempt : int, optional
        The attempt whose corrected plan and constraints to use; by default the
        learned plan and constraints of the session.
    objects : mapping of str to TaskObject, optional
        Objects to use (with their meshes) instead of bare parts named after the plan.

    Returns
    -------
    TaskFile
        Objects in order of first appearance in the plan, the constraints the
        plan uses, one step per plan step. The ``iros15`` stage block keeps the
        rest: where the plan's ``wait`` steps were, rows of unused symbols, and
        for an attempt its state, effort counts and precision.

    Raises
    ------
    ThirdhandError
        If the session or attempt does not exist or has no plan.
    """
    try:
        se = study.subjects[subject][scene][session]
    except KeyError:
        raise ThirdhandError(
            f"{study.path}: no session {subject}/{scene}/{session} in the user study"
        ) from None
    block: dict[str, Any] = {"subject": subject, "scene": scene, "session": session}
    if attempt is None:
        plan, table = se.plan, se.symbols
    else:
        found = [a for a in se.attempts if a.index == attempt]
        if not found:
            raise ThirdhandError(
                f"{study.path}: no attempt {attempt} in {subject}/{scene}/{session}; "
                f"attempts are {[a.index for a in se.attempts]}"
            )
        a = found[0]
        plan, table = a.corrected_plan, a.corrected_st
        block.update(
            attempt=attempt, state=a.state, effort={k: dict(v) for k, v in a.effort.items()}
        )
        if a.corrected_precision is not None:
            block["corrected_precision"] = {
                k: None if v is None else list(v)
                for k, v in dataclasses.asdict(a.corrected_precision).items()
            }
    where = f"{subject}/{scene}/{session}" + (f"/{attempt}" if attempt is not None else "")
    if plan is None:
        raise ThirdhandError(f"{study.path}: {where} has no plan")
    steps = [s for s in plan if isinstance(s, StudyStep)]
    names = list(dict.fromkeys(n for s in steps for n in (s.parent, s.child)))
    known = dict(objects or {})
    block["waits"] = [i for i, s in enumerate(plan) if s == WAIT]
    block["unused_symbols"] = {k: list(v) for k, v in table.unused.items()}
    path = Path(study.path)
    source = InputFile.from_path(path) if path.is_file() else InputFile(path=study.path)
    return TaskFile.new(
        objects=[known.get(n, TaskObject(name=n, kind="part")) for n in names],
        constraints=list(table.constraints.values()),
        plan=[
            TaskStep(
                action=s.action or "action",
                parent=s.parent,
                child=s.child,
                symbol=s.symbol,
                constraint=s.symbol if s.symbol in table.constraints else None,
            )
            for s in steps
        ],
        stages={"iros15": block},
        inputs=[source],
    )
