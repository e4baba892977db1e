"""Fits are computed once (issue 19): what ``station annotate`` and ``station compare`` cost on
a day of 200 and of 2000 descents with the fits stored in the session (``fits.jsonl``) against
the same command with every fit computed again (the station before the store, and the first
command after a recording).

The sessions are made as tests/session_helpers.py makes them (the model's own times as ALGE
lines in a raw log, two items). Each ``annotate`` marks one descent invalid (the results CSV is
rewritten from a replay, as ``station export`` writes it). Figures in this process (the
command's start-up not included; benchmarks/startup.py measures that), the median of
``--repeats`` runs; the commands "as typed" are whole processes of the ``station`` command.

Run: python benchmarks/fits_once.py [--sizes 200,2000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.cli.main import main  # noqa: E402
from station.session.fitstore import FITS  # noqa: E402
from tests.session_helpers import make_session  # noqa: E402


def _run(*args: str) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        code = main(list(args))
    assert code == 0, args
    return time.perf_counter() - t0


def _process(*args: str) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "station", *args], check=True, capture_output=True,
                   env=env)  # fmt: skip
    return time.perf_counter() - t0


def _without_fits(session: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(os.path.join(session, FITS))


def measure(n: int, repeats: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp:
        session = str(make_session(Path(tmp), order="AB" * (n // 2), interval_s=20.0))
        out: dict[str, float] = {}

        def annotate(k: int) -> float:
            return _run("annotate", session, "--descents", str(1 + k % n), "--invalid", f"r{k}")

        _without_fits(session)
        out["annotate, every fit computed"] = annotate(0)  # also stores the fits
        out["annotate, fits stored"] = statistics.median(annotate(k) for k in range(1, repeats + 1))
        out["annotate as typed, fits stored"] = statistics.median(
            _process("annotate", session, "--descents", "2", "--invalid", f"p{k}")
            for k in range(repeats)
        )
        _without_fits(session)
        out["compare, every fit computed"] = _run("compare", session)
        out["compare, fits stored"] = statistics.median(
            _run("compare", session) for _ in range(repeats)
        )
        size = os.path.getsize(os.path.join(session, FITS))
        out["fits.jsonl kB per descent"] = size / n / 1024
        return out


def main_() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="200,2000")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    figures = {n: measure(n, args.repeats) for n in sizes}
    names = list(figures[sizes[0]])
    print(f"{'':34}" + "".join(f"{n:>9d} desc" for n in sizes) + "   ratio last/first")
    for name in names:
        row = [figures[n][name] for n in sizes]
        unit = "" if "kB" in name else " s"
        cells = "".join(f"{v:>12.2f}{unit}" if unit else f"{v:>14.2f}" for v in row)
        print(f"{name:34}{cells}   {row[-1] / row[0]:6.2f}×")
    last = figures[sizes[-1]]
    for what in ("annotate", "compare"):
        before, after = last[f"{what}, every fit computed"], last[f"{what}, fits stored"]
        gain = before / after
        print(f"{what} at {sizes[-1]}: {before:.2f} s -> {after:.2f} s ({gain:.1f}× faster)")


if __name__ == "__main__":
    main_()
