"""Data flows one way: the core is pure, only the UI imports textual, nothing imports the
simulators. Every module is imported, so a broken import anywhere fails here first."""

from __future__ import annotations

import ast
import importlib
import pkgutil
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import station

ROOT = Path(station.__file__).resolve().parent

#: the pure core: no serial port, no threads, no UI toolkit, no file or process I/O
CORE = ("station.model", "station.timing", "station.survey.track", "station.survey.polar")
CORE_MODULES = (
    "station.session.processor",
    "station.session.analysis",
    "station.session.day",
    "station.session.records",
)
FORBIDDEN_IN_CORE = {"serial", "threading", "textual", "subprocess", "socket", "asyncio"}
#: files of the core that read input files by design (the times file, the traverse data)
READS_FILES = {"station.timing.timesfile", "station.model.traverse"}


def all_modules() -> list[str]:
    found = pkgutil.walk_packages([str(ROOT)], prefix="station.")
    return sorted(m.name for m in found if not m.name.endswith("__main__"))


def is_core(name: str) -> bool:
    return name in CORE_MODULES or any(name == c or name.startswith(c + ".") for c in CORE)


def imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def module_path(name: str) -> Path:
    rel = name.split(".")[1:]
    p = ROOT.joinpath(*rel)
    return p / "__init__.py" if p.is_dir() else p.with_suffix(".py")


def test_every_module_imports():
    for name in all_modules():
        importlib.import_module(name)


def test_the_core_imports_no_serial_threads_ui_or_processes():
    offenders = []
    for name in filter(is_core, all_modules()):
        roots = {n.split(".")[0] for n in imported_roots(module_path(name))}
        bad = roots & FORBIDDEN_IN_CORE
        if bad:
            offenders.append(f"{name}: {sorted(bad)}")
    assert offenders == []


def test_the_core_does_no_file_io():
    io_call = re.compile(r"\b(open|os\.(remove|rename|replace|makedirs|fsync|write))\(")
    offenders = [
        name
        for name in filter(is_core, all_modules())
        if name not in READS_FILES and io_call.search(module_path(name).read_text())
    ]
    assert offenders == []


#: the simulated timer, test days and surveys: tools beside the station, which never imports them
SIMULATORS = "station.simulators"


def test_only_station_ui_imports_textual_and_nothing_imports_simulators():
    offenders = []
    for name in all_modules():
        roots = {n.split(".")[0] for n in imported_roots(module_path(name))}
        if "textual" in roots and not name.startswith("station.ui"):
            offenders.append(f"{name}: textual")
        simulators = {n for n in imported_roots(module_path(name)) if n.startswith(SIMULATORS)}
        if simulators and not name.startswith(SIMULATORS):
            offenders.append(f"{name}: simulators")
    assert offenders == []


def test_the_command_line_loads_no_ui_toolkit_and_no_simulators():
    code = (
        "import sys, station.cli.main, station.model.fit, station.model.traverse,"
        " station.timing.timesfile;"
        "bad = [m for m in sys.modules if m.split('.')[0] == 'textual'"
        " or m.startswith('station.simulators')];"
        "print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


# ----------------------------------------------------------------------------- the layers
#
# Data flows one way, and so do imports: a module imports only from its own layer or the
# layers below it. From the bottom:
#
#   0  station (the version), errors, files, numbers, limits, yamlfile,   what every part uses
#      runtime
#   1  station.survey, station.timing      readings -> track profile; timer bytes -> descents
#   2  station.model                       the particle model, fits, the day's comparison
#   3  station.session                     a test day: config, raw log, acquisition, replay,
#                                          the recorded session object
#   4  station.store                       the season store (built on recorded sessions)
#   5  station.report                      text, tables and pages for people
#   6  station.ui                          the trackside terminal UI
#   7  station.cli                         the ``station`` command (and station.__main__)
#   8  station.simulators                  the simulated timer, days and surveys (tools)
#
# station.surveys holds data only (the demo run's files).
#
# The UI sits under the command line: ``station live`` starts the UI, the UI never runs a
# command. Every import counts, also one inside a function or under TYPE_CHECKING: a
# function-local import is a dependency all the same, only a later one.

LAYERS = {
    "station": 0, "station.errors": 0, "station.files": 0, "station.numbers": 0,
    "station.limits": 0, "station.yamlfile": 0, "station.runtime": 0,
    "station.survey": 1, "station.timing": 1,
    "station.model": 2,
    "station.session": 3,
    "station.store": 4,
    "station.report": 5,
    "station.ui": 6,
    "station.cli": 7, "station.__main__": 7,
    "station.simulators": 8, "station.surveys": 0,
}  # fmt: skip
#: the modules of station.cli that share code between the command modules (not commands)
CLI_SHARED = {"station.cli", "station.cli.main", "station.cli.common", "station.cli.console",
              "station.cli.tui"}  # fmt: skip


def layer_of(module: str) -> int:
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        key = ".".join(parts[:n])
        if key in LAYERS:
            return LAYERS[key]
    raise AssertionError(f"{module}: in no layer; add it to LAYERS in this test")


def every_module() -> list[str]:
    return [*all_modules(), "station.__main__"]


def _for_annotations_only(tree: ast.AST) -> set[int]:
    """The ids of the import nodes under ``if TYPE_CHECKING:`` (never run)."""
    ids: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for stmt in node.body:
                ids |= {id(n) for n in ast.walk(stmt)}
    return ids


def station_imports(name: str, annotations: bool = True) -> set[str]:
    """The station modules ``name`` imports anywhere in its source (module level, in a
    function, and under TYPE_CHECKING unless ``annotations`` is false): ``from station.session
    import store`` is an import of ``station.session.folder``, the module, not the package."""
    known = set(every_module())
    path = module_path(name) if name != "station.__main__" else ROOT / "__main__.py"
    tree = ast.parse(path.read_text())
    skip = set() if annotations else _for_annotations_only(tree)
    out: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            subs = [f"{node.module}.{a.name}" for a in node.names]
            targets = [s for s in subs if s in known] or [node.module]
        else:
            continue
        out |= {t for t in targets if t == "station" or t.startswith("station.")}
    return out - {name}


def import_graph(annotations: bool = True) -> dict[str, set[str]]:
    return {name: station_imports(name, annotations) for name in every_module()}


def test_no_module_imports_from_a_higher_layer():
    offenders = [
        f"{name} (layer {layer_of(name)}) imports {dep} (layer {layer_of(dep)})"
        for name, deps in import_graph().items()
        for dep in sorted(deps)
        if layer_of(dep) > layer_of(name)
    ]
    assert offenders == []


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
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
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_cycles_finds_a_circle_of_imports():
    """The check itself: a circle of three and a module importing itself through a fourth."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"f"}, "f": {"e"}}
    assert cycles(graph) == [["a", "b", "c"], ["e", "f"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_circle_of_imports():
    """No circle of imports that run, at the top of a module or in a function (where a circle
    only fails later, in the middle of a command). An import under TYPE_CHECKING runs nowhere
    and may name a module that imports this one, for an annotation; it still counts for the
    layers above."""
    assert cycles(import_graph(annotations=False)) == []


def test_the_command_line_is_imported_by_nothing_but_its_entry_points():
    """``station/cli`` is the top: python -m station and the console script enter it, no
    other part of the package calls into it."""
    offenders = [
        f"{name} imports {dep}"
        for name, deps in import_graph().items()
        for dep in deps
        if dep.startswith("station.cli")
        and not name.startswith("station.cli")
        and name != "station.__main__"
    ]
    assert offenders == []
    scripts = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["station"] == "station.cli.main:main"


def test_no_command_module_imports_another():
    """Each group of commands stands on the shared modules (common, console, tui), never on
    another group: a command module imported by another is a circle waiting to happen."""
    offenders = [
        f"{name} imports {dep}"
        for name, deps in import_graph().items()
        if name.startswith("station.cli.") and name not in CLI_SHARED
        for dep in deps
        if dep.startswith("station.cli.") and dep not in CLI_SHARED
    ]
    assert offenders == []


def test_the_season_store_is_used_by_the_command_line_the_ui_and_the_report_only():
    allowed = ("station.store", "station.cli", "station.ui", "station.report")
    offenders = [
        f"{name} imports {dep}"
        for name, deps in import_graph().items()
        for dep in deps
        if (dep == "station.store" or dep.startswith("station.store."))
        and not any(name == a or name.startswith(a + ".") for a in allowed)
    ]
    assert offenders == []


def test_no_argument_namespace_outside_the_command_line():
    """The session services take what they need, not a command's parsed arguments (the
    simulators are tools with command lines of their own)."""
    offenders = [
        name
        for name in all_modules()
        if not name.startswith(("station.cli", SIMULATORS))
        and re.search(r"\bargparse\b", module_path(name).read_text())
    ]
    assert offenders == []


def test_only_the_edges_import_the_season_store():
    """The season store (a database) is an edge: the command line, the UI and the report use
    it; the core and the session code never do."""
    allowed = ("station.cli", "station.ui", "station.report", "station.store")
    offenders = [
        name
        for name in all_modules()
        if not name.startswith(allowed)
        and any(n == "station.store" or n.startswith("station.store.")
                for n in imported_roots(module_path(name)))
    ]  # fmt: skip
    assert offenders == []
