"""Start-up: a command imports only what it uses (benchmarks/startup.py measures the time)."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.conftest import ROOT

#: README.md, "Worked example", step 3
FIT = ["fit", "--survey", "surveys/demo_run.yaml", "--times", "surveys/demo_descent.csv",
       "--mass", "88", "--pressure-hpa", "835", "--temperature-c", "-4",
       "--humidity-pct", "70"]  # fmt: skip
HEAVY = ["pandas", "scipy.stats", "textual", "serial", "simulators", "station.session.records"]

#: run in a fresh interpreter: main(argv), then which modules it imported, as JSON
SCRIPT = """
import contextlib, io, json, sys
from station.cli.main import main
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    try:
        status = main(json.loads(sys.argv[1]))
    except SystemExit as exc:  # argparse: usage errors
        status = exc.code
names = json.loads(sys.argv[2])
print(json.dumps({"status": status, **{m: m in sys.modules for m in names}}))
"""


def loaded_after(argv: list[str]) -> dict[str, bool]:
    """Run ``station argv`` in a fresh interpreter; its status, and which modules it loaded."""
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, json.dumps(argv), json.dumps([*HEAVY, "numpy"])],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def test_the_readme_fit_loads_no_pandas_scipy_stats_ui_or_serial_port():
    loaded = loaded_after(FIT)
    assert loaded["status"] == 0 and loaded["numpy"]
    assert [m for m in HEAVY if loaded[m]] == []


def test_a_usage_error_loads_no_numerics():
    loaded = loaded_after(["fit", "--mass", "-1"])
    assert loaded["status"] == 2
    assert not loaded["numpy"] and [m for m in HEAVY if loaded[m]] == []


def test_the_parser_of_one_command_is_the_parser_of_that_command():
    """main builds only the named command's group: the same commands, in the same order, as
    the full parser, so a command missing from the table would not run at all."""
    import argparse

    from station.cli.main import COMMANDS, build_parser

    def commands(ap: argparse.ArgumentParser) -> list[str]:
        sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
        return list(sub.choices)

    assert commands(build_parser()) == list(COMMANDS)
    for name, group in COMMANDS.items():
        assert name in commands(build_parser(name))
        assert set(commands(build_parser(name))) == {c for c, g in COMMANDS.items() if g == group}
