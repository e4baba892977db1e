"""Fits are computed once (issue 19): what ``station annotate`` and ``station compare`` cost on
a day of 200 and of 2000 descents with the fits stored in the session (``fits.jsonl``) against
the same command with every fit computed again (the station before the store, and the first
command after a recording).

The sessions are made as tests/session_helpers.py makes them (the model's own times as ALGE
lines in a raw log, two items). Each ``annotate`` marks one descent invalid. The first one
after the day (no fits stored, no state of the results CSV) replays it and fits every descent;
then the results CSV is changed in place, without a replay (its state says it is the replay's:
station/session/resultsstate.py); "replayed" is the same annotate with that state removed
first, i.e. the station before it (the whole day replayed from the stored fits and the CSV
rewritten). Figures in this process (the command's start-up not included;
benchmarks/startup.py measures that), the median of ``--repeats`` runs; the commands "as
typed" are whole processes of the ``station`` command. Issue 19's target: annotate at 2000
descents ≤ 1.5× its time at 200, as typed and in this process.

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
import typing
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.cli.main import main  # noqa: E402
from station.session.fitstore import FITS  # noqa: E402
from station.session.resultsstate import STATE  # noqa: E402
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


def _without(session: str, name: str) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(os.path.join(session, name))


def _without_fits(session: str) -> None:
    _without(session, FITS)


def measure_annotate(n: int, repeats: int, session: str | None = None) -> dict[str, float]:
    """The annotate figures of a day of ``n`` descents (made here unless given)."""
    if session is None:
        with tempfile.TemporaryDirectory() as tmp:
            made = str(make_session(Path(tmp), order="AB" * (n // 2), interval_s=20.0))
            return measure_annotate(n, repeats, made)
    out: dict[str, float] = {}

    def annotate(k: int) -> float:
        return _run("annotate", session, "--descents", str(1 + k % n), "--invalid", f"r{k}")

    def typed(k: int) -> float:
        return _process("annotate", session, "--descents", str(2 + k % n), "--invalid", f"p{k}")

    def replayed(run: typing.Callable[[int], float], k: int) -> float:
        _without(session, STATE)
        return run(k)

    _without_fits(session)
    out["annotate, every fit computed"] = annotate(0)  # also stores the fits
    out["annotate, replayed, fits stored"] = statistics.median(
        replayed(annotate, k) for k in range(1, repeats + 1)
    )
    annotate(0)  # the results CSV with its state again
    out["annotate, in place"] = statistics.median(annotate(k) for k in range(1, 3 * repeats + 1))
    out["annotate as typed, replayed"] = statistics.median(
        replayed(typed, k) for k in range(repeats)
    )
    typed(0)
    out["annotate as typed, in place"] = statistics.median(typed(k) for k in range(repeats))
    return out


def paired(sessions: dict[int, str], repeats: int) -> dict[str, dict[int, float]]:
    """``annotate`` in place of each day in turn (200, 2000, 200, 2000 …), in this process
    and as typed, so that both sizes see the same load of the shared machine: the medians.
    The days' results CSVs must have their state (as :func:`measure_annotate` leaves them)."""
    runs: dict[str, dict[int, list[float]]] = {
        "in place": {n: [] for n in sessions}, "as typed, in place": {n: [] for n in sessions}
    }  # fmt: skip
    for k in range(repeats):
        for n, session in sessions.items():
            d = str(3 + k % (n - 2))
            runs["in place"][n].append(_run("annotate", session, "--descents", d, "--invalid",
                                            f"q{k}"))  # fmt: skip
            runs["as typed, in place"][n].append(
                _process("annotate", session, "--descents", d, "--invalid", f"t{k}")
            )
    return {how: {n: statistics.median(v) for n, v in by.items()} for how, by in runs.items()}


def annotate_figures(
    sizes: list[int], repeats: int, compare: bool = False
) -> tuple[dict[int, dict[str, float]], dict[str, dict[int, float]]]:
    """Each day's figures (:func:`measure`), then the paired in-place figures of all."""
    with contextlib.ExitStack() as stack:
        made = {}
        for n in sizes:
            tmp = Path(stack.enter_context(tempfile.TemporaryDirectory()))
            made[n] = str(make_session(tmp, order="AB" * (n // 2), interval_s=20.0))
        figures = {n: measure(n, repeats, compare, made[n]) for n in sizes}
        return figures, paired(made, 3 * repeats)


def measure(n: int, repeats: int, compare: bool, session: str) -> dict[str, float]:
    out = measure_annotate(n, repeats, session)
    if not compare:
        return out
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
    ap.add_argument("--no-compare", action="store_true", help="annotate only")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    figures, pair = annotate_figures(sizes, args.repeats, not args.no_compare)
    names = list(figures[sizes[0]])
    print(f"{'':34}" + "".join(f"{n:>10d} desc" for n in sizes) + "   ratio last/first")
    for name in names:
        row = [figures[n][name] for n in sizes]
        unit = "" if "kB" in name else " s"
        cells = "".join(f"{v:>12.3f}{unit}" if unit else f"{v:>14.2f}" for v in row)
        print(f"{name:34}{cells}   {row[-1] / row[0]:6.2f}×")
    last = figures[sizes[-1]]
    for what, after_name in (
        ("annotate", "annotate, in place"),
        ("compare", "compare, fits stored"),
    ):
        if f"{what}, every fit computed" not in last:
            continue
        before, after = last[f"{what}, every fit computed"], last[after_name]
        gain = before / after
        print(f"{what} at {sizes[-1]}: {before:.2f} s -> {after:.3f} s ({gain:.1f}× faster)")
    print(f"annotate in place, each size in turn ({3 * args.repeats} runs each; target ≤ 1.5×):")
    for how, by in pair.items():
        a, b = by[sizes[0]], by[sizes[-1]]
        print(f"  {how:20} {sizes[-1]} / {sizes[0]} descents: {b * 1e3:7.1f} / {a * 1e3:7.1f} ms"
              f"  {b / a:.2f}×")  # fmt: skip


if __name__ == "__main__":
    main_()
