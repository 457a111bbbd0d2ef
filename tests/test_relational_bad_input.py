"""Bad input to the relational IRL readers and commands: one clear error, never a hang."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from thirdhand.errors import OptionError, TaskFileError
from thirdhand.relational.boosting import fit_boosted
from thirdhand.relational.cli import MAX_LEGS, app
from thirdhand.relational.csi import fit_rcsi
from thirdhand.relational.data import random_pairs
from thirdhand.relational.domains.blocks import blocks_domain, blocks_mdp, floor_state
from thirdhand.relational.domains.chair import chair_domain
from thirdhand.relational.logic import Atom, RelationalError
from thirdhand.relational.mdp import ground


def _task(path: Path, objects: list[str], plan: list[dict[str, str]]) -> Path:
    doc = {"schema": "thirdhand.task/1", "objects": [{"name": n} for n in objects], "plan": plan}
    path.write_text(json.dumps(doc))
    return path


def test_state_with_unknown_predicate_is_rejected() -> None:
    bad = floor_state(3) | {Atom("under", ("b1", "b2"))}
    with pytest.raises(RelationalError, match=r"initial state 0: unknown predicate 'under'"):
        ground(blocks_domain(3), [bad])
    wrong_arity = floor_state(3) | {Atom("on", ("b1",))}
    with pytest.raises(RelationalError, match="on expects 2"):
        ground(blocks_domain(3), [wrong_arity])
    with pytest.raises(RelationalError, match="unknown object 'b9'"):
        ground(blocks_domain(3), [floor_state(3) | {Atom("clear", ("b9",))}])


def test_trajectory_file_with_unknown_object_or_no_plan(tmp_path: Path) -> None:
    bad = _task(
        tmp_path / "bad.json", ["seating"], [{"parent": "seating", "child": "arm7", "symbol": "c1"}]
    )
    res = CliRunner().invoke(app, ["learn", str(bad)])
    assert isinstance(res.exception, TaskFileError)
    assert "bad.json: plan[0].child: unknown object 'arm7'" in str(res.exception)
    nojson = tmp_path / "nojson.json"
    nojson.write_text("{not json")
    res = CliRunner().invoke(app, ["learn", str(nojson)])
    assert isinstance(res.exception, TaskFileError) and "invalid JSON" in str(res.exception)


def test_empty_expert_set() -> None:
    mdp = blocks_mdp(3)
    rnd = [(mdp, random_pairs(mdp, 10, np.random.default_rng(0)))]
    with pytest.raises(RelationalError, match="no expert example"):
        fit_boosted([])
    with pytest.raises(RelationalError, match="no expert example"):
        fit_rcsi([(mdp, np.zeros(0, dtype=np.int64))], rnd)
    res = CliRunner().invoke(app, ["learn"])
    assert isinstance(res.exception, RelationalError) and "no demonstration" in str(res.exception)
    res = CliRunner().invoke(app, ["learn", "--synth", "0"])
    assert isinstance(res.exception, RelationalError) and "no demonstration" in str(res.exception)


@pytest.mark.parametrize("legs", ["0", "-1", str(MAX_LEGS + 1), "1000000000"])
def test_legs_out_of_range(tmp_path: Path, legs: str) -> None:
    good = _task(
        tmp_path / "good.json",
        ["seating", "leg1"],
        [{"parent": "seating", "child": "leg1", "symbol": "c1"}],
    )
    res = CliRunner().invoke(app, ["learn", str(good), "--legs", legs])
    assert isinstance(res.exception, OptionError)
    assert f"--legs: expected an integer >= 1 and <= {MAX_LEGS}, got {legs}" in str(res.exception)
    with pytest.raises(RelationalError, match="non-negative number of legs"):
        chair_domain(-1)


def test_blocks_in_a_cycle_are_rejected_not_looped_on() -> None:
    from thirdhand.relational.domains.blocks import tower_heights

    cyc = frozenset(
        {Atom("on", ("b1", "b2")), Atom("on", ("b2", "b1")), Atom("on", ("b3", "floor"))}
    )
    with pytest.raises(RelationalError, match="cycle"):
        tower_heights(cyc)
    hang = frozenset({Atom("on", ("b1", "b2")), Atom("on", ("b2", "b1")), Atom("on", ("b3", "b1"))})
    with pytest.raises(RelationalError, match="does not stand on the floor"):
        tower_heights(hang)
