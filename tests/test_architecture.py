"""The shape of the code (docs/architecture.md), checked from the source's import statements:
no import cycle between modules of app/, no package importing one above it, sim imported only
where the simulated stand is opened, app/ root at most 8 modules, no module over 600 lines."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# Lowest first: a package may import only packages at its own rank or below (docs/architecture.md).
RANKS = {
    "app": 0, "app.errors": 0, "app.version": 0, "app.formatting": 0, "app.lines": 0, "app.logs": 0,
    "app.files": 1,
    "app.io": 2,
    "app.stand": 3,
    "app.records": 4,
    "app.procedure": 5, "app.certificate": 5,
    "app.validation": 6,
    "app.cli": 7, "app.gui": 7, "app.web": 7, "app.__main__": 8,
}  # fmt: skip
SIM_OPENERS = {"app.stand.open", "app.stand.simulated", "app.procedure.simulate"}


def _modules() -> dict[str, Path]:
    out = {}
    for path in (ROOT / "app").rglob("*.py"):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        out[name.removesuffix(".__init__")] = path
    return out


def _imports(path: Path, modules: dict[str, Path]) -> tuple[set[str], set[str]]:
    """(app modules imported at run time, top-level packages imported), TYPE_CHECKING blocks
    left out."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    typing_only: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            typing_only.update(id(n) for child in node.body for n in ast.walk(child))
    found: set[str] = set()
    tops: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        names: list[str] = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            subs = [f"{node.module}.{a.name}" for a in node.names]
            names = [s for s in subs if s in modules] or [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            tops.add(name.split(".")[0])
            if name in modules:
                found.add(name)
    return found, tops


def _package(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2])


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(path, modules)[0] - {name} for name, path in modules.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle_between_modules() -> None:
    assert _cycles(_graph()) == []


def test_the_cycle_finder_finds_one() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_package_imports_one_above_it() -> None:
    wrong = []
    for module, imported in _graph().items():
        mine = RANKS[_package(module)]
        for other in imported:
            if RANKS[_package(other)] > mine:
                wrong.append(f"{module} -> {other}")
    assert wrong == []


def test_app_imports_sim_only_where_the_simulated_stand_is_opened() -> None:
    modules = _modules()
    importers = {name for name, path in modules.items() if "sim" in _imports(path, modules)[1]}
    assert importers <= SIM_OPENERS, sorted(importers - SIM_OPENERS)
    assert importers, "the simulated stand is opened somewhere"


def test_app_root_holds_at_most_eight_modules() -> None:
    assert len(list((ROOT / "app").glob("*.py"))) <= 8


@pytest.mark.parametrize("package", ["app", "dsp", "hardware", "sim"])
def test_no_source_module_over_600_lines(package: str) -> None:
    long = [
        f"{path.relative_to(ROOT)}: {count}"
        for path in (ROOT / package).rglob("*.py")
        if "migrations" not in path.parts
        and (count := len(path.read_text(encoding="utf-8").splitlines())) > 600
    ]
    assert long == []
