"""The layout's rules, read from the source: no import cycle, fem never imports contact, no
module over 500 lines (the benchmarks' too), no file opened by the solver or geometry,
``__init__`` files of the library that only re-export, an explicit ``__all__`` everywhere,
a handful of modules at the top of ``contact/``."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("fem", "contact", "benchmarks")
#: The library: its ``__init__`` files only re-export.
LIBRARY = ("fem", "contact")
MAX_LINES = 500
#: Modules at the top of ``contact/`` (``__init__.py`` counted).
MAX_TOP = 6
#: Subpackages whose modules must not touch files (stateless geometry, a solver that writes
#: nothing): the application reads and writes.
NO_FILES = ("contact.geometry", "contact.solver")
#: Calls that read or write files.
FILE_CALLS = {
    "open", "read_text", "write_text", "read_bytes", "write_bytes", "save", "savez",
    "savez_compressed", "load", "loadtxt", "savetxt", "read_mesh", "write_mesh", "mkdir",
    "unlink", "rmtree",
}
#: Modules that exist to read or write files.
FILE_MODULES = {"os", "pathlib", "shutil", "tempfile", "io", "json", "pickle", "meshio",
                "tomllib", "tomli"}


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join(parts)] = path
    return found


MODULES = _modules()


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _import_nodes(tree: ast.AST, typing: bool = False) -> list[ast.Import | ast.ImportFrom]:
    """Every import the module executes, at any depth; under ``if TYPE_CHECKING`` too
    where ``typing``."""
    out: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _type_checking(node) and not typing:
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            out.append(node)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return out


def _imports(name: str, path: Path, typing: bool = False) -> set[str]:
    """The project modules ``name`` imports (a ``from package import module`` names both)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    targets: set[str] = set()
    for node in _import_nodes(ast.parse(path.read_text()), typing):
        if isinstance(node, ast.Import):
            bases = [alias.name for alias in node.names]
            names: list[str] = []
        else:
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            bases = [base]
            names = [alias.name for alias in node.names]
        for base in bases:
            if base.split(".")[0] not in PACKAGES:
                continue
            submodules = {f"{base}.{n}" for n in names} & MODULES.keys()
            targets.update(submodules)
            if len(submodules) < len(names) or not names:
                # a name that is not a submodule comes from the package's __init__
                targets.add(base)
    return {t for t in targets if t in MODULES and t != name}


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return out


def test_the_rules_see_the_modules():
    # a guard for the guards: the scan finds the packages and their imports
    assert "contact.solver.iteration" in MODULES and "fem.statics" in MODULES
    assert "fem.assembly" in GRAPH["fem"] and "benchmarks._common" in MODULES
    assert any(t.startswith("contact.solver") for t in GRAPH["contact"])
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle():
    # function-level imports count: a cycle hidden in a function is still a cycle
    cycles = _cycles(GRAPH)
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_no_import_cycle_even_in_type_hints():
    # modules that name each other's types only are still two halves of one concern
    graph = {name: _imports(name, path, typing=True) for name, path in MODULES.items()}
    cycles = _cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_fem_never_imports_contact():
    bad = {m: sorted(t for t in GRAPH[m] if t.startswith("contact"))
           for m in MODULES if m.startswith("fem")}
    assert not {m: t for m, t in bad.items() if t}


@pytest.mark.parametrize("name", sorted(MODULES))
def test_module_size(name):
    lines = MODULES[name].read_text().count("\n")
    assert lines <= MAX_LINES, f"{MODULES[name].relative_to(ROOT)}: {lines} lines"


@pytest.mark.parametrize("name", sorted(m for m in MODULES if m.startswith(NO_FILES)))
def test_solver_and_geometry_open_no_files(name):
    tree = ast.parse(MODULES[name].read_text())
    calls = sorted({
        node.func.id if isinstance(node.func, ast.Name) else node.func.attr
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, (ast.Name, ast.Attribute))
        and (node.func.id if isinstance(node.func, ast.Name) else node.func.attr) in FILE_CALLS
    })
    modules = sorted({
        alias.name.split(".")[0] for node in _import_nodes(tree) if isinstance(node, ast.Import)
        for alias in node.names
    } | {
        (node.module or "").split(".")[0] for node in _import_nodes(tree)
        if isinstance(node, ast.ImportFrom) and not node.level
    } & FILE_MODULES)
    modules = [m for m in modules if m in FILE_MODULES]
    assert not calls and not modules, f"{name}: calls {calls}, imports {modules}"


@pytest.mark.parametrize(
    "name",
    sorted(m for m in MODULES if MODULES[m].name == "__init__.py" and m.startswith(LIBRARY)),
)
def test_init_only_reexports(name):
    tree = ast.parse(MODULES[name].read_text())
    for node in tree.body[1:] if ast.get_docstring(tree) else tree.body:
        if isinstance(node, ast.ImportFrom) and (node.level or node.module == "__future__"):
            continue
        targets = node.targets if isinstance(node, ast.Assign) else [
            node.target] if isinstance(node, ast.AnnAssign) else []
        if targets and all(isinstance(t, ast.Name) and t.id.startswith("__") for t in targets):
            continue
        pytest.fail(f"{MODULES[name].relative_to(ROOT)}:{node.lineno}: not a re-export")


@pytest.mark.parametrize("name", sorted(MODULES))
def test_explicit_all(name):
    tree = ast.parse(MODULES[name].read_text())
    assert ast.get_docstring(tree), f"{name}: no module docstring"
    if name.rpartition(".")[2].startswith("_") and MODULES[name].name != "__init__.py":
        return
    names = {getattr(t, "id", "") for node in tree.body if isinstance(node, ast.Assign)
             for t in node.targets} | {getattr(node.target, "id", "") for node in tree.body
                                       if isinstance(node, ast.AnnAssign)}
    assert "__all__" in names, f"{name}: no __all__"


def test_the_top_of_contact_is_read_in_one_look():
    # the application's entry, the exceptions, the TOML reader: the rest lives in rooms
    top = sorted(p.name for p in (ROOT / "contact").glob("*.py"))
    assert len(top) <= MAX_TOP, f"{len(top)} modules at the top of contact/: {top}"


def test_the_readme_is_short_enough_to_read():
    # what it is, the set-up, a picture, how to run a scene, where to read on: the rest in docs/
    assert (ROOT / "README.md").stat().st_size < 14_000
