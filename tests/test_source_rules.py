"""Rules the package's source keeps: pose maths through :mod:`thirdhand.se3`, one
module of array type aliases, no research code inside the package."""

from __future__ import annotations

import ast
from pathlib import Path

import thirdhand

PACKAGE = Path(thirdhand.__file__).parent
ALIASES = {"FloatArray", "IntArray", "IndexArray", "BoolArray"}


def _modules() -> list[tuple[Path, ast.Module]]:
    return [(p, ast.parse(p.read_text())) for p in sorted(PACKAGE.rglob("*.py"))]


def test_rotations_go_through_se3() -> None:
    """Only se3 imports scipy's Rotation: every conversion, inversion and mean is one
    tested function (issue 31)."""
    offenders = []
    for path, tree in _modules():
        if path.name == "se3.py":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module == "scipy.spatial.transform":
                offenders.append(str(path.relative_to(PACKAGE)))
    assert offenders == []


def test_array_aliases_are_defined_once() -> None:
    """``FloatArray`` and its kin are assigned in :mod:`thirdhand.arrays` only."""
    offenders = []
    for path, tree in _modules():
        if path.name == "arrays.py":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Assign | ast.AnnAssign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names = {t.id for t in targets if isinstance(t, ast.Name)}
                if names & ALIASES and not _under_type_checking(tree, node):
                    offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno}")
    assert offenders == []


def _under_type_checking(tree: ast.Module, target: ast.AST) -> bool:
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.If)
            and isinstance(node.test, ast.Name)
            and node.test.id == "TYPE_CHECKING"
            and any(target is sub for stmt in node.body for sub in ast.walk(stmt))
        ):
            return True
    return False


def test_no_research_inside_the_package() -> None:
    """Experiments and evaluation recipes live in the repository's ``research/``."""
    assert not (PACKAGE / "experiments").exists()
    for _path, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                mods = (
                    [a.name for a in node.names]
                    if isinstance(node, ast.Import)
                    else [node.module or ""]
                )
                assert not any(m == "research" or m.startswith("research.") for m in mods)
