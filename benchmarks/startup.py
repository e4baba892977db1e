"""Start-up: the whole-process wall time of the README's ``station fit`` example against the
bare import of what a fit cannot do without (numpy, scipy.optimize, scipy.interpolate).

A test engineer runs ``station fit`` many times a day, and every command pays for what
``station`` imports before it does its work. The floor is the libraries the fit needs; the
figure that matters is how far above that floor the whole command is (target ≤ 1.25×). The
command is the one README.md shows under "Worked example", run as a user runs it: the
``station`` console script of this environment, a fresh process each time, from the checkout.

Both commands run alternately (so a change in the machine's load hits both alike), ``--repeats``
times each; it prints the median and the minimum wall time of each, the ratio of the medians,
and which heavy optional modules (scipy.stats, pandas, textual, serial) the fit loaded.

``station`` runs OpenBLAS on one thread (``station.runtime.one_blas_thread``), which also
makes its import of numpy and scipy cheaper than the bare import with the default pool. So that
the ratio cannot hide station's own overhead behind that, the bare import also runs with
``OPENBLAS_NUM_THREADS=1`` (alternating with the others) and the ratio to it is printed too.

``--only season-list`` and ``--only compare`` measure two more commands against the bare
``python -c 'import numpy, scipy'`` (target ≤ 1.5×) and against the bare import of what their
work needs (SQLAlchemy for the store; numpy, scipy.optimize and scipy.interpolate for the joint
fit and the track): ``station season list`` on a store of two days, and ``station compare`` on a
session of eight descents (ABBAABBA), both made once in a temporary folder by the tests'
helpers. Wall and CPU time, the CPU time less moved by the machine's load. ``--only all`` runs
the three.

Run: python benchmarks/startup.py [--repeats N] [--only fit|season-list|compare|all]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: README.md, "Worked example: the demo run", step 3, word for word
FIT_ARGS = [
    "fit", "--survey", "surveys/demo_run.yaml", "--times", "surveys/demo_descent.csv",
    "--mass", "88", "--pressure-hpa", "835", "--temperature-c", "-4", "--humidity-pct", "70",
]  # fmt: skip
BARE = [sys.executable, "-c", "import numpy, scipy.optimize, scipy.interpolate"]
#: modules a fit does not need; loading one of them is start-up time spent for nothing
HEAVY = ("scipy.stats", "pandas", "textual", "serial")


def station_script() -> list[str]:
    """The ``station`` console script next to this interpreter (as installed by pip)."""
    script = Path(sys.executable).parent / "station"
    if script.exists():
        return [str(script)]
    found = shutil.which("station")
    if found is None:
        sys.exit("startup: no `station` script; install the package (pip install -e .)")
    return [found]


def wall(cmd: list[str], env: dict[str, str] | None = None) -> float:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env)
    dt = time.perf_counter() - t0
    if done.returncode != 0:
        sys.exit(f"startup: {' '.join(cmd)} failed ({done.returncode}): {done.stderr.strip()}")
    return dt


def heavy_modules(script: list[str]) -> list[str]:
    """The HEAVY modules the fit imports, from one run under ``python -X importtime``."""
    cmd = [sys.executable, "-X", "importtime", script[0], *FIT_ARGS]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True)
    names = {line.rsplit("|", 1)[-1].strip() for line in done.stderr.splitlines()}
    return [h for h in HEAVY if h in names]


#: the floor issue 19 measures against: what a fit's numerics import
BARE_FIT = [sys.executable, "-c", "import scipy.integrate, scipy.optimize"]


def measure(repeats: int = 15) -> dict[str, list[float]]:
    """Wall times (s) of the README's ``station fit``, the bare imports, alternating; and the
    CPU time of ``station fit`` and of the bare import (``*_cpu``), less moved by the load.

    Every command runs with its modules' bytecode cached, as an installed package has it (pip
    compiles it): ``PYTHONDONTWRITEBYTECODE`` (set in the test machine's environment) is left
    out, and the first runs write the caches. ``fit_nocache`` is ``station fit`` with it set:
    its modules compiled again on every run, as this environment otherwise does."""
    script = station_script()
    fit = [*script, *FIT_ARGS]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    one = {**env, "OPENBLAS_NUM_THREADS": "1"}
    nocache = {**env, "PYTHONDONTWRITEBYTECODE": "1"}
    wall(fit, env), wall(BARE, env), wall(BARE_FIT, env)  # caches warm; not counted
    names = ("fit", "bare", "one", "bare_fit", "fit_nocache", "fit_cpu", "bare_fit_cpu")
    times: dict[str, list[float]] = {k: [] for k in names}
    for _ in range(repeats):
        c0 = _children_cpu()
        times["fit"].append(wall(fit, env))
        c1 = _children_cpu()
        times["bare_fit"].append(wall(BARE_FIT, env))
        c2 = _children_cpu()
        times["fit_cpu"].append(c1 - c0)
        times["bare_fit_cpu"].append(c2 - c1)
        times["bare"].append(wall(BARE, env))
        times["one"].append(wall(BARE, one))
        times["fit_nocache"].append(wall(fit, nocache))
    return times


#: the floor of the other commands: the two libraries every numeric command loads
BARE_TOP = [sys.executable, "-c", "import numpy, scipy"]


def make_fixtures(base: Path) -> dict[str, list[str]]:
    """A season store of two days and a session of eight descents under ``base``; the command
    line of ``station season list`` and of ``station compare`` on them."""
    import datetime as dt

    sys.path.insert(0, str(ROOT))
    from tests.season_helpers import make_day
    from tests.session_helpers import make_session

    (base / "day").mkdir()
    session = make_session(base / "day")
    days = [
        make_day(
            base / "season", f"d{k}", dt.date(2026, 1, 4 + k), "ABBA", {"A": 0.008, "B": 0.009}
        )
        for k in (1, 2)
    ]
    store = str(base / "season.db")
    script = station_script()
    wall([*script, "season", "add", "--store", store, *map(str, days)])
    return {
        "season-list": [*script, "season", "list", "--store", store],
        "compare": [*script, "compare", str(session)],
    }


#: what each command cannot do without: the libraries its work imports
NEEDS = {
    "season-list": [sys.executable, "-c", "import sqlalchemy"],
    "compare": BARE,
}


def measure_against(cmd: list[str], floors: list[list[str]], repeats: int) -> list[list[float]]:
    """Wall and CPU times (s) of ``cmd`` and of each bare import in ``floors``, alternating:
    ``[cmd wall, cmd cpu, floor wall, floor cpu, ...]``."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    runs = [cmd, *floors]
    for run in runs:  # caches warm (and the compare's fits); not counted
        wall(run, env)
    times: list[list[float]] = [[] for _ in range(2 * len(runs))]
    for _ in range(repeats):
        for k, run in enumerate(runs):
            c0 = _children_cpu()
            times[2 * k].append(wall(run, env))
            times[2 * k + 1].append(_children_cpu() - c0)
    return times


def report_against_top(name: str, cmd: list[str], repeats: int) -> None:
    """``cmd`` against the bare import of numpy and scipy (target 1.5x) and against the bare
    import of the libraries its work needs (``NEEDS``)."""
    floors = [BARE_TOP, NEEDS[name]]
    times = measure_against(cmd, floors, repeats)
    m = [statistics.median(t) for t in times]
    print(f"station {name}  median {m[0] * 1e3:5.0f} ms, CPU {m[1] * 1e3:5.0f} ms")
    for k, floor in enumerate(floors, start=1):
        bare = f"python -c {floor[2]!r}"
        print(f"  {bare}  median {m[2 * k] * 1e3:5.0f} ms, CPU {m[2 * k + 1] * 1e3:5.0f} ms")
        print(f"    ratio of medians: wall {m[0] / m[2 * k]:.2f}x, CPU {m[1] / m[2 * k + 1]:.2f}x")


def _children_cpu() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=15, help="runs of each command (≥ 10)")
    ap.add_argument("--only", choices=("fit", "season-list", "compare", "all"), default="fit")
    args = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}")
    print(f"runs of each, alternating: {args.repeats}")
    if args.only in ("fit", "all"):
        report_fit(args.repeats)
    if args.only != "fit":
        with tempfile.TemporaryDirectory() as tmp:
            commands = make_fixtures(Path(tmp))
            for name, cmd in commands.items():
                if args.only in (name, "all"):
                    report_against_top(name, cmd, args.repeats)


def report_fit(repeats: int) -> None:
    script = station_script()
    times = measure(repeats)
    t_fit, t_bare, t_one, t_sci = times["fit"], times["bare"], times["one"], times["bare_fit"]
    m_fit, m_bare, m_one, m_sci = (statistics.median(t) for t in (t_fit, t_bare, t_one, t_sci))
    print(f"station {' '.join(FIT_ARGS)}")
    print(f"  median {m_fit * 1e3:7.0f} ms   min {min(t_fit) * 1e3:7.0f} ms")
    print(f"python -c {BARE[2]!r}")
    print(f"  median {m_bare * 1e3:7.0f} ms   min {min(t_bare) * 1e3:7.0f} ms")
    print(f"ratio of medians  {m_fit / m_bare:.2f}x   (min/min {min(t_fit) / min(t_bare):.2f}x)")
    print("the same import with OPENBLAS_NUM_THREADS=1 (as station loads the libraries)")
    print(f"  median {m_one * 1e3:7.0f} ms   min {min(t_one) * 1e3:7.0f} ms")
    print(f"ratio of medians  {m_fit / m_one:.2f}x   (min/min {min(t_fit) / min(t_one):.2f}x)")
    print(f"python -c {BARE_FIT[2]!r} (issue 19's floor; target 1.1x)")
    print(f"  median {m_sci * 1e3:7.0f} ms   min {min(t_sci) * 1e3:7.0f} ms")
    print(f"ratio of medians  {m_fit / m_sci:.2f}x   (min/min {min(t_fit) / min(t_sci):.2f}x)")
    c_fit, c_sci = statistics.median(times["fit_cpu"]), statistics.median(times["bare_fit_cpu"])
    print(f"  CPU time: station fit {c_fit * 1e3:.0f} ms, the bare import {c_sci * 1e3:.0f} ms: "
          f"{c_fit / c_sci:.2f}x")  # fmt: skip
    m_nc = statistics.median(times["fit_nocache"])
    print(f"station fit compiling its modules on every run (PYTHONDONTWRITEBYTECODE=1): median "
          f"{m_nc * 1e3:.0f} ms, {m_nc / m_sci:.2f}x the bare import")  # fmt: skip
    loaded = heavy_modules(script)
    print(f"heavy modules the fit loads: {', '.join(loaded) if loaded else 'none'}")


if __name__ == "__main__":
    main()
