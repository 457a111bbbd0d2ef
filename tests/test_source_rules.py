"""Rules the package's source keeps: pose maths through :mod:`thirdhand.se3`, one
module of array type aliases, no research code inside the package."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import thirdhand

PACKAGE = Path(thirdhand.__file__).parent
ALIASES = {"FloatArray", "IntArray", "IndexArray", "BoolArray"}


def _modules() -> list[tuple[Path, ast.Module]]:
    return [(p, ast.parse(p.read_text())) for p in sorted(PACKAGE.rglob("*.py"))]


def test_rotations_go_through_se3() -> None:
    """Only se3 imports scipy's Rotation: every conversion, inversion and mean is one
    tested function."""
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


def _import_graph(package: str = "thirdhand"):  # type: ignore[no-untyped-def]
    import grimp

    return grimp.build_graph(package, exclude_type_checking_imports=True, cache_dir=None)


def _circles(graph) -> list[list[str]]:  # type: ignore[no-untyped-def]
    """The import circles of a grimp graph: its strongly connected components of more
    than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []

    def enter(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        work.append((node, iter(sorted(graph.find_modules_directly_imported_by(node)))))

    for root in sorted(graph.modules):
        if root in index:
            continue
        work: list = []
        enter(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    enter(child)
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    circles.append(sorted(component))
    return circles


def test_no_import_circle() -> None:
    """No module reaches itself through imports, counting those made inside functions
    (an import deferred into a function is there for start-up time, never to hide a
    circle); the layer order itself is the import-linter contract in pyproject.toml."""
    assert _circles(_import_graph()) == []


def test_an_import_circle_inside_functions_is_found(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two modules that import each other, one of them only inside a function, and a
    third outside the circle."""
    pkg = tmp_path / "circ"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    import circ.b\n")
    (pkg / "b.py").write_text("import circ.a\n")
    (pkg / "c.py").write_text("import circ.a\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _circles(_import_graph("circ")) == [["circ.a", "circ.b"]]


def test_no_module_imports_another_packages_private_module() -> None:
    """``thirdhand.a._x`` is imported from inside ``thirdhand.a`` only."""
    graph = _import_graph()
    offenders = []
    for module in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(module):
            parts = imported.split(".")
            private = [i for i, p in enumerate(parts) if p.startswith("_") and p != "__main__"]
            if not private:
                continue
            owner = ".".join(parts[: private[0]])
            if not (module == owner or module.startswith(owner + ".")):
                offenders.append(f"{module} -> {imported}")
    assert offenders == []


def test_one_opencv_distribution() -> None:
    """cv2 comes from one distribution: two (``opencv-python-headless`` beside the
    ``opencv-contrib-python`` mediapipe requires) overwrite each other's files, and
    which one wins depends on the order they were installed in."""
    import importlib.metadata
    import tomllib

    project = tomllib.loads((PACKAGE.parents[1] / "pyproject.toml").read_text())["project"]
    deps = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        deps += extra
    named = {d.split(">")[0].split("=")[0].split("<")[0].strip() for d in deps}
    assert {n for n in named if n.startswith("opencv")} == {"opencv-contrib-python"}
    providers = importlib.metadata.packages_distributions().get("cv2", [])
    assert len(set(providers)) <= 1, providers


#: Calls that read a file's bytes without the reading policy of :mod:`thirdhand.readlimits`.
RAW_READS = {
    "open",
    "read_text",
    "read_bytes",
    "load",
    "loads",
    "loadtxt",
    "genfromtxt",
    "fromfile",
    "read_table",
    "read_csv",
    "ParquetFile",
}
#: The policy: a function that reads raw checks the path first with one of these.
POLICY = {"check_regular", "read_input", "read_text_input", "open_input", "read_json"}
#: Raw reads that are not a user's input, each with why.
RAW_READ_EXEMPT = {
    "fileops.py": "outputs only: backups of a file being replaced, locks and syncs of folders",
    "io/c3d/writer.py": "reads back the temporary file it just wrote",
    "io/motive/block.py": "reads the data block of the file motive.header._read_header opened "
    "through open_input",
    "segment/model.py:builtin_model": "a model file shipped inside the package",
    "batch.py:dask_processes": "the scheduler file of the scheduler it started, in its own "
    "temporary folder",
    "perception/_deps.py:quiet_native_stderr": "opens /dev/null to silence native libraries",
    "live/mcap_source.py": "follows an MCAP file while its recorder appends to it, after "
    "being_written found it a regular file",
}


def _call_name(node: ast.Call) -> str | None:
    f = node.func
    if isinstance(f, ast.Name):
        return f.id
    if isinstance(f, ast.Attribute):
        return f.attr
    return None


def _writes(node: ast.Call) -> bool:
    """An ``open`` for writing (a mode with w, a or x), not a read."""
    modes = [a for a in node.args[1:2]] + [k.value for k in node.keywords if k.arg == "mode"]
    return any(
        isinstance(m, ast.Constant) and isinstance(m.value, str) and set(m.value) & set("wax")
        for m in modes
    )


def _raw_reads(fn: ast.AST) -> list[int]:
    lines = []
    for node in ast.walk(fn):
        if not isinstance(node, ast.Call):
            continue
        name = _call_name(node)
        if name not in RAW_READS or (name == "open" and _writes(node)):
            continue
        base = node.func.value if isinstance(node.func, ast.Attribute) else None
        if name == "open" and isinstance(base, ast.Name) and base.id[:1].isupper():
            continue  # a class's own ``open`` (ReviewSession.open), not a file read
        if name in ("load", "loads"):
            # json.load(s)/np.load/yaml.load/tomllib.loads of bytes already read are parsers;
            # a file object or path handed to them is a raw read.
            base = node.func.value if isinstance(node.func, ast.Attribute) else None
            if not (isinstance(base, ast.Name) and base.id in ("np", "numpy")) and name != "load":
                continue
            if isinstance(base, ast.Name) and base.id in ("yaml", "tomllib", "pickle"):
                continue
            if name == "load" and not (isinstance(base, ast.Name) and base.id in ("np", "json")):
                continue
        if name in ("read_text", "read_bytes") and not isinstance(node.func, ast.Attribute):
            continue
        lines.append(node.lineno)
    return lines


def test_every_reader_goes_through_the_reading_policy() -> None:
    """A function that opens or reads a file first checks it (regular, bounded, interruptible).

    A private helper (``_name``) may read a path its public caller checked: its
    module must then call the policy.
    """
    offenders = []
    for path, tree in _modules():
        rel = path.relative_to(PACKAGE).as_posix()
        if rel == "readlimits.py" or rel in RAW_READ_EXEMPT:
            continue
        in_module = {_call_name(c) for c in ast.walk(tree) if isinstance(c, ast.Call)}
        for fn in ast.walk(tree):
            if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            raw = [
                n
                for n in _raw_reads(fn)
                if not any(
                    n in range(inner.lineno, (inner.end_lineno or inner.lineno) + 1)
                    for inner in ast.walk(fn)
                    if inner is not fn and isinstance(inner, ast.FunctionDef)
                )
            ]
            if not raw or f"{rel}:{fn.name}" in RAW_READ_EXEMPT:
                continue
            called = {_call_name(c) for c in ast.walk(fn) if isinstance(c, ast.Call)}
            if fn.name.startswith("_") and in_module & POLICY:
                continue
            if not called & POLICY:
                offenders.append(f"{rel}:{raw[0]} ({fn.name})")
    assert offenders == []


def test_every_module_has_a_layer() -> None:
    """Every top-level module and package of thirdhand is named in a layer of the
    import-linter contract, so none escapes it."""
    import re
    import tomllib

    config = tomllib.loads((PACKAGE.parents[1] / "pyproject.toml").read_text())
    (contract,) = config["tool"]["importlinter"]["contracts"]
    named = set(re.findall(r"thirdhand\.([\w]+)", " ".join(contract["layers"])))
    tops = {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
    tops |= {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert tops - named == set()
