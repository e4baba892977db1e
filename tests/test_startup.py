"""Start-up: a command imports only what it uses (benchmarks/startup.py measures the time)."""

from __future__ import annotations

import json
import os
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


#: run in a fresh interpreter: main(argv), then the threads of each BLAS library loaded, as JSON
BLAS_SCRIPT = """
import contextlib, io, json, sys
from station.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    status = main(json.loads(sys.argv[1]))
from threadpoolctl import threadpool_info
blas = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
print(json.dumps({"status": status, "blas_threads": blas}))
"""


def blas_threads_after(argv: list[str], **env: str) -> list[int]:
    """Run ``station argv`` in a fresh interpreter with the BLAS thread variables of ``env``
    only; the number of threads of every BLAS library it loaded."""
    clean = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARS}
    out = subprocess.run(
        [sys.executable, "-c", BLAS_SCRIPT, json.dumps(argv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
        env={**clean, **env},
    )
    loaded = json.loads(out.stdout)
    assert loaded["status"] == 0 and loaded["blas_threads"]  # numpy's OpenBLAS, scipy's
    return loaded["blas_threads"]


BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def test_the_fit_runs_on_one_blas_thread_unless_the_user_chose_another_number():
    """A pool of BLAS threads stalls the spline's eigh for 70-90 ms on a busy machine and
    spins beside the imports; the station's matrices are too small to gain from it."""
    assert set(blas_threads_after(FIT)) == {1}
    assert set(blas_threads_after(FIT, OPENBLAS_NUM_THREADS="2")) == {2}


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
