"""Data flows one way: the core imports neither the simulators nor the UI toolkit."""

from __future__ import annotations

import subprocess
import sys


def test_core_imports_no_simulators_and_no_textual():
    code = (
        "import sys, station.cli, station.fit, station.traverse, station.dae, station.timesfile;"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('simulators', 'textual')];"
        "print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_only_station_ui_imports_textual():
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "station"
    pattern = re.compile(r"^\s*(from|import)\s+textual\b", re.M)
    offenders = [
        str(p.relative_to(root))
        for p in root.rglob("*.py")
        if "ui" not in p.relative_to(root).parts[:1] and pattern.search(p.read_text())
    ]
    assert offenders == []
    assert not any(
        re.search(r"^\s*(from|import)\s+simulators\b", p.read_text(), re.M)
        for p in root.rglob("*.py")
    )
