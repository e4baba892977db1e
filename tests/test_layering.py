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
