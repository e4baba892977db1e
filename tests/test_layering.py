"""Data flows one way: the core is pure, only the UI imports textual, nothing imports the
simulators. Every module is imported, so a broken import anywhere fails here first."""

from __future__ import annotations

import ast
import importlib
import pkgutil
import re
import subprocess
import sys
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


def test_only_station_ui_imports_textual_and_nothing_imports_simulators():
    offenders = []
    for name in all_modules():
        roots = {n.split(".")[0] for n in imported_roots(module_path(name))}
        if "textual" in roots and not name.startswith("station.ui"):
            offenders.append(f"{name}: textual")
        if "simulators" in roots:
            offenders.append(f"{name}: simulators")
    assert offenders == []


def test_the_command_line_loads_no_ui_toolkit_and_no_simulators():
    code = (
        "import sys, station.cli.main, station.model.fit, station.model.traverse,"
        " station.timing.timesfile;"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('simulators', 'textual')];"
        "print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


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
