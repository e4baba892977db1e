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

``station`` runs OpenBLAS on one thread (station/cli/main.py, ``one_blas_thread``), which also
makes its import of numpy and scipy cheaper than the bare import with the default pool. So that
the ratio cannot hide station's own overhead behind that, the bare import also runs with
``OPENBLAS_NUM_THREADS=1`` (alternating with the others) and the ratio to it is printed too.

Run: python benchmarks/startup.py [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=15, help="runs of each command (≥ 10)")
    args = ap.parse_args()
    script = station_script()
    fit = [*script, *FIT_ARGS]
    one = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    wall(fit), wall(BARE)  # warm the file cache; not counted
    t_fit, t_bare, t_one = [], [], []
    for _ in range(args.repeats):
        t_fit.append(wall(fit))
        t_bare.append(wall(BARE))
        t_one.append(wall(BARE, one))
    m_fit, m_bare, m_one = (statistics.median(t) for t in (t_fit, t_bare, t_one))
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}")
    print(f"runs of each, alternating: {args.repeats}")
    print(f"station {' '.join(FIT_ARGS)}")
    print(f"  median {m_fit * 1e3:7.0f} ms   min {min(t_fit) * 1e3:7.0f} ms")
    print(f"python -c {BARE[2]!r}")
    print(f"  median {m_bare * 1e3:7.0f} ms   min {min(t_bare) * 1e3:7.0f} ms")
    print(f"ratio of medians  {m_fit / m_bare:.2f}x   (min/min {min(t_fit) / min(t_bare):.2f}x)")
    print("the same import with OPENBLAS_NUM_THREADS=1 (as station loads the libraries)")
    print(f"  median {m_one * 1e3:7.0f} ms   min {min(t_one) * 1e3:7.0f} ms")
    print(f"ratio of medians  {m_fit / m_one:.2f}x   (min/min {min(t_fit) / min(t_one):.2f}x)")
    loaded = heavy_modules(script)
    print(f"heavy modules the fit loads: {', '.join(loaded) if loaded else 'none'}")


if __name__ == "__main__":
    main()
