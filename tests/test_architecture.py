"""The shape of the code (docs/architecture.md), checked from the source's import statements:
no import cycle between modules of dsp/, hardware/, sim/ and app/; no package importing one
above it (imports under `if TYPE_CHECKING:` count: a type is a dependency too); dsp/ imports
only numpy, scipy, the standard library and itself; hardware/ and sim/ never import app/, only
sim/ may import hardware/ and sim/ (below app, which imports sim only where the simulated stand
is opened); app/ root at most 8 modules, no module over 600 lines."""

from __future__ import annotations

import ast
import functools
import sys
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
PACKAGES = ("dsp", "hardware", "sim", "app")
# what each package below app/ may import besides itself and the standard library
BELOW_APP = {
    "dsp": {"numpy", "scipy"},
    "hardware": {"numpy", "nidaqmx", "pyvisa"},
    "sim": {"numpy", "scipy", "pyvisa", "pyvisa_sim", "yaml", "dsp", "hardware"},
}
STDLIB = frozenset(sys.stdlib_module_names)


def _modules(packages: tuple[str, ...] = ("app",)) -> dict[str, Path]:
    out = {}
    for package in packages:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = path
    return out


@functools.cache
def _parsed(path: Path) -> ast.Module:
    """The file's syntax tree, parsed once per test process (the tests here walk every file
    several times)."""
    return ast.parse(path.read_text(encoding="utf-8"))


def _imports(
    path: Path, modules: dict[str, Path], *, typing: bool = False, source: str | None = None
) -> tuple[set[str], set[str]]:
    """(modules of `modules` imported, top-level packages imported): at run time, or with
    `typing` also those under `if TYPE_CHECKING:`. `source` stands for the file's text."""
    tree = _parsed(path) if source is None else ast.parse(source)
    typing_only: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            typing_only.update(id(n) for child in node.body for n in ast.walk(child))
    found: set[str] = set()
    tops: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in typing_only and not typing:
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


def _graph(packages: tuple[str, ...] = ("app",), *, typing: bool = False) -> dict[str, set[str]]:
    """Module -> the modules it imports (of `packages`; with `typing` also type-only ones)."""
    modules = _modules(packages)
    return {
        name: _imports(path, modules, typing=typing)[0] - {name} for name, path in modules.items()
    }


def _rank_violations(graph: dict[str, set[str]]) -> list[str]:
    """'importer -> imported' for every app module importing a package ranked above its own."""
    wrong = []
    for module, imported in graph.items():
        if not module.startswith("app"):
            continue
        mine = RANKS[_package(module)]
        for other in imported:
            if other.startswith("app") and RANKS[_package(other)] > mine:
                wrong.append(f"{module} -> {other}")
    return sorted(wrong)


def _foreign_imports(package: str, extra: dict[str, str] | None = None) -> list[str]:
    """'module: name' for every top-level package a module of `package` (below app) imports
    beyond the standard library, itself and BELOW_APP[package], type-only imports included.
    `extra`: more modules of the package, by name, as source text."""
    allowed = STDLIB | BELOW_APP[package] | {package}
    modules = _modules((package,))
    sources: dict[str, tuple[Path, str | None]] = {n: (p, None) for n, p in modules.items()}
    sources.update({n: (ROOT / package / "extra.py", text) for n, text in (extra or {}).items()})
    return sorted(
        f"{name}: {top}"
        for name, (path, text) in sources.items()
        for top in _imports(path, modules, typing=True, source=text)[1]
        if top not in allowed
    )


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
    assert _cycles(_graph(PACKAGES)) == []


def test_the_cycle_finder_finds_one() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_package_imports_one_above_it() -> None:
    assert _rank_violations(_graph(typing=True)) == []


def test_a_type_checking_import_that_breaks_the_ranks_is_caught() -> None:
    """A stand module (rank 3) naming the run record (records, rank 4) for its type hints only:
    invisible at run time, still a dependency upwards."""
    source = (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n"
        "    from app.records.run_record import RunRecord\n"
        "def f(record: 'RunRecord') -> None: ...\n"
    )
    modules = _modules()
    module = ROOT / "app" / "stand" / "typed_upwards.py"
    runtime, _ = _imports(module, modules, source=source)
    typed, _ = _imports(module, modules, typing=True, source=source)
    assert runtime == set() and typed == {"app.records.run_record"}
    graph = {"app.stand.typed_upwards": typed, "app.records.run_record": set()}
    assert _rank_violations(graph) == ["app.stand.typed_upwards -> app.records.run_record"]


@pytest.mark.parametrize("package", sorted(BELOW_APP))
def test_the_packages_below_app_import_only_what_their_rank_allows(package: str) -> None:
    """dsp: numpy, scipy and the standard library; hardware: its drivers' libraries; sim also
    dsp and hardware; none of them app (type-only imports included)."""
    assert _foreign_imports(package) == []


def test_an_import_below_app_that_breaks_the_ranks_is_caught() -> None:
    typed_app = (
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from app.records import x\n"
    )
    assert _foreign_imports("sim", {"sim.upwards": typed_app}) == ["sim.upwards: app"]
    assert _foreign_imports("hardware", {"hardware.up": "import sim.stand\n"}) == [
        "hardware.up: sim"
    ]
    lazy = "def f():\n    from hardware import teds\n    import h5py\n"
    assert _foreign_imports("dsp", {"dsp.up": lazy}) == ["dsp.up: h5py", "dsp.up: hardware"]
    assert _foreign_imports("sim", {"sim.down": "import hardware.teds\nimport dsp\n"}) == []


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
