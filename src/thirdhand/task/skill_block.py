"""Validation of the skill library in a task file's ``stages.primitives`` block.

The stage blocks are free-form (a later stage adds its block without a schema
change), but the skill library written by ``learn`` is read back by people and
programs, so when it is present it is checked on load:

- ``stages.primitives.skill_library``: the skills, ids ``0…K−1`` in order, each
  with its ProMP (``mean`` of ``n_weights × dims`` numbers, a packed lower
  Cholesky factor of matching size) and its level Gaussian;
- ``stages.primitives.constraints.<key>.skills``: per example, the steps
  ``{skill, start, end}`` in time order, each naming a skill of the library.

A problem is reported as one line with its JSON location, e.g.
``stages.primitives.constraints.c2.skills[0].steps[3].skill: unknown skill 7
(the library has skills 0..3)``.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from thirdhand.task.errors import json_location


class _Block(BaseModel):
    model_config = ConfigDict(extra="allow", allow_inf_nan=False, strict=True)


class _ProMP(_Block):
    kind: str
    n_weights: int = Field(ge=1)
    dims: int = Field(ge=1)
    duration: float = Field(gt=0)
    noise: float = Field(gt=0)
    mean: list[float]
    cov_cholesky_lower: list[float]


class _Skill(_Block):
    id: int
    weight: float = Field(ge=0, le=1)
    level_mean: list[float]
    level_var: list[float]
    promp: _ProMP


class _Library(_Block):
    n_skills: int = Field(ge=1)
    rate_hz: float = Field(gt=0)
    skills: list[_Skill]


class _Step(_Block):
    skill: int
    start: float
    end: float


class _Example(_Block):
    source: str
    steps: list[_Step]


def _model_problem(model: type[BaseModel], data: Any, where: str) -> str | None:
    try:
        model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        loc = json_location(err["loc"])
        msg = "required field is missing" if err["type"] == "missing" else err["msg"]
        sep = "" if not loc or loc.startswith("[") else "."
        return f"{where}{sep}{loc}: {msg}"
    return None


def _library_problem(lib: Any, where: str) -> tuple[str | None, int]:
    problem = _model_problem(_Library, lib, where)
    if problem is not None:
        return problem, 0
    n = lib["n_skills"]
    if len(lib["skills"]) != n:
        return f"{where}.skills: expected {n} skills (n_skills), got {len(lib['skills'])}", 0
    n_levels = None
    for i, s in enumerate(lib["skills"]):
        at = f"{where}.skills[{i}]"
        if s["id"] != i:
            return f"{at}.id: expected {i} (skills are numbered in order), got {s['id']}", 0
        p = s["promp"]
        f = p["n_weights"] * p["dims"]
        if len(p["mean"]) != f:
            return (
                f"{at}.promp.mean: expected n_weights × dims = {f} numbers, got {len(p['mean'])}",
                0,
            )
        packed = f * (f + 1) // 2
        if len(p["cov_cholesky_lower"]) != packed:
            return (
                f"{at}.promp.cov_cholesky_lower: expected {packed} numbers, "
                f"got {len(p['cov_cholesky_lower'])}",
                0,
            )
        if len(s["level_var"]) != len(s["level_mean"]):
            return (
                f"{at}.level_var: expected {len(s['level_mean'])} numbers like level_mean, "
                f"got {len(s['level_var'])}",
                0,
            )
        if any(v <= 0 for v in s["level_var"]):
            return f"{at}.level_var: variances must be positive", 0
        if n_levels is not None and len(s["level_mean"]) != n_levels:
            return (
                f"{at}.level_mean: expected {n_levels} numbers like skills[0], "
                f"got {len(s['level_mean'])}",
                0,
            )
        n_levels = len(s["level_mean"])
    return None, n


def _examples_problem(examples: Any, where: str, n_skills: int) -> str | None:
    if not isinstance(examples, list):
        return f"{where}: expected a list of explained examples, got {type(examples).__name__}"
    for j, ex in enumerate(examples):
        at = f"{where}[{j}]"
        problem = _model_problem(_Example, ex, at)
        if problem is not None:
            return problem
        prev_end = None
        for k, st in enumerate(ex["steps"]):
            sat = f"{at}.steps[{k}]"
            if not 0 <= st["skill"] < n_skills:
                return (
                    f"{sat}.skill: unknown skill {st['skill']} "
                    f"(the library has skills 0..{n_skills - 1})"
                )
            if st["end"] < st["start"]:
                return f"{sat}: end {st['end']} s is before start {st['start']} s"
            if prev_end is not None and st["start"] < prev_end - 1e-9:
                return (
                    f"{sat}.start: {st['start']} s is before the previous step's end "
                    f"{prev_end} s (steps are in time order)"
                )
            prev_end = st["end"]
    return None


def skill_block_problem(primitives: dict[str, Any] | None) -> str | None:
    """The first problem of the skill library in a ``stages.primitives`` block, or None.

    Parameters
    ----------
    primitives : dict or None
        The block (None or a block without ``skill_library`` and without any
        constraint's ``skills``: nothing to check).

    Returns
    -------
    str or None
        ``"<JSON location>: <problem>"``.
    """
    if primitives is None:
        return None
    where = "stages.primitives"
    constraints = primitives.get("constraints", {})
    explained = (
        [k for k, c in constraints.items() if isinstance(c, dict) and "skills" in c]
        if isinstance(constraints, dict)
        else []
    )
    if "skill_library" not in primitives:
        if explained:
            return (
                f"{where}.constraints.{explained[0]}.skills: refers to skills, but "
                f"{where}.skill_library is missing"
            )
        return None
    problem, n_skills = _library_problem(primitives["skill_library"], f"{where}.skill_library")
    if problem is not None:
        return problem
    for key in explained:
        problem = _examples_problem(
            constraints[key]["skills"], f"{where}.constraints.{key}.skills", n_skills
        )
        if problem is not None:
            return problem
    return None
