"""Start-up: a command imports only what it uses (benchmarks/startup.py measures the time)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

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


#: the station modules the README fit needs: a module imported beyond these (a plot, the
#: session records, the points-CSV reader, the comparison) is start-up time for every fit
FIT_MODULES = {
    "station", "station.errors", "station.files", "station.limits", "station.numbers",
    "station.yamlfile",
    "station.cli", "station.cli.main", "station.cli.common", "station.cli.fit",
    "station.model", "station.model.air", "station.model.estimate", "station.model.fit",
    "station.model.fit_result", "station.model.fit_search",
    "station.model.physics", "station.model.timer", "station.model.track_error",
    "station.survey", "station.survey.formats", "station.survey.gsi", "station.survey.load",
    "station.survey.network", "station.survey.polar",
    "station.survey.smoothing", "station.survey.track",
    "station.timing", "station.timing.timesfile",
}  # fmt: skip

#: run in a fresh interpreter: main(argv) (or nothing), then every module loaded, as JSON
MODULES_SCRIPT = """
import contextlib, io, json, sys
argv = json.loads(sys.argv[1])
if argv:
    from station.cli.main import main
    with contextlib.redirect_stdout(io.StringIO()):
        status = main(argv)
else:
    import numpy, scipy.optimize, scipy.interpolate
    status = 0
print(json.dumps({"status": status, "modules": sorted(sys.modules)}))
"""


def modules_after(argv: list[str]) -> set[str]:
    """Every module ``station argv`` loads in a fresh interpreter (``[]``: the bare import of
    numpy, scipy.optimize and scipy.interpolate, the floor of benchmarks/startup.py)."""
    out = subprocess.run(
        [sys.executable, "-c", MODULES_SCRIPT, json.dumps(argv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    )
    loaded = json.loads(out.stdout)
    assert loaded["status"] == 0
    return set(loaded["modules"])


def test_the_readme_fit_loads_the_libraries_of_a_fit_yaml_and_its_own_modules_only():
    """Beyond what the bare import of numpy, scipy.optimize and scipy.interpolate loads, the
    fit may load yaml (the survey) and the station modules in FIT_MODULES, nothing else."""
    extra = modules_after(FIT) - modules_after([])
    unexpected = {
        m
        for m in extra
        if m not in FIT_MODULES and m.split(".")[0] not in ("yaml", "_yaml")
        and not m.startswith("_cython_")  # the Cython runtime a scipy routine loads on use
    }  # fmt: skip
    assert unexpected == set(), "import these where they are used, not on the fit's way"
    assert {"station.model.fit", "station.survey.track", "yaml"} <= extra  # it did the work


def test_a_survey_of_coordinates_reads_no_gsi_and_draws_no_plot(tmp_path):
    rows = ["id,e,n,h"]
    for i in range(40):  # a plane falling 0.3 m per metre, the photocells' posts beside it
        rows.append(f"P{i:02d},{5.0 * i:.1f},0.0,{1000.0 - 1.5 * i:.2f}")
    rows += ["C1L,40.0,3.0,988.0", "C1R,40.0,-3.0,988.0"]
    rows += ["C2L,150.0,3.0,955.0", "C2R,150.0,-3.0,955.0"]
    (tmp_path / "pts.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    survey = tmp_path / "run.yaml"
    survey.write_text(
        'name: plane\npoints: pts.csv\nprofile_pattern: "^P\\\\d+$"\nphotocells:\n'
        "  - {id: C1, points: [C1L, C1R]}\n  - {id: C2, points: [C2L, C2R]}\n"
    )
    loaded = modules_after(["survey", str(survey), "--json"])
    assert "station.survey.coords" in loaded
    assert not {"station.survey.gsi", "station.report.track_plot", "matplotlib"} & loaded


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


def test_help_and_a_wrong_command_load_no_config_survey_or_numerics():
    """``station --help`` imports every command's module to list them: their sessions, configs,
    surveys and numerics are imported inside the commands, not at the top."""
    for argv in (["--help"], ["no-such-command"]):
        loaded = subprocess.run(
            [sys.executable, "-c", SCRIPT, json.dumps(argv),
             json.dumps(["yaml", "numpy", "scipy", "station.survey.load",
                         "station.session.config", *HEAVY[:-1]])],
            cwd=ROOT, capture_output=True, text=True, check=True,
        )  # fmt: skip
        found = json.loads(loaded.stdout)
        assert found["status"] in (0, 2)
        assert [m for m, was in found.items() if m != "status" and was] == [], argv


def test_the_fit_runs_without_the_garbage_collector_and_gives_it_back():
    """The fit (mostly importing numpy and scipy) runs with the collector off; a caller in the
    same process has it on again afterwards, also when the command failed."""
    import contextlib
    import gc
    import io

    from station.cli.main import main

    seen = []
    import station.cli.fit as fit_cli

    real = fit_cli.cmd_fit

    def spy(args):
        seen.append(gc.isenabled())
        return real(args)

    assert gc.isenabled()
    try:
        fit_cli.cmd_fit = spy
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            assert main(FIT) == 0
            with pytest.raises(SystemExit):  # a usage error: argparse exits
                main([*FIT[:-2], "--humidity-pct", "300"])
            assert gc.isenabled()
            assert main([*FIT[:2], "no-such-survey.yaml", *FIT[3:]]) == 2
    finally:
        fit_cli.cmd_fit = real
    assert seen == [False, False] and gc.isenabled()
