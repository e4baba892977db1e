"""What ``station annotate`` costs now that it brings the session's results CSV up to date:
the first one after the day replays it (every fit, as ``station export`` does) and writes the
CSV with its state; the later ones change the rows they concern in place
(station/session/resultsstate.py), a model change of descent 1 too (it used to be replayed:
its fit gave the survey covariance). And what ``station sessions`` pays to try a session's
recording lock.

Sessions of 8 and 40 descents are made as tests/session_helpers.py makes them (the model's
own times as ALGE lines in a raw log). Each figure is the median of 3 runs (the first
annotate: one run), in this process (the command's own start-up, ``benchmarks/startup.py``,
not included).

Run: python benchmarks/annotate_rewrite.py
"""

from __future__ import annotations

import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.cli.main import main  # noqa: E402
from station.session.folder import RecordingLock, recording_state  # noqa: E402
from station.session.resultsstate import STATE  # noqa: E402
from tests.session_helpers import make_session  # noqa: E402


def _run(*args: str) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        code = main(list(args))
    assert code == 0, args
    return time.perf_counter() - t0


def main_() -> None:
    for n in (8, 40):
        with tempfile.TemporaryDirectory() as tmp:
            session = str(make_session(Path(tmp), order="AB" * (n // 2)))
            first = _run("annotate", session, "--descents", "2", "--invalid", "r")
            runs = [_run("annotate", session, "--descents", "2", "--invalid", f"r{k}")
                    for k in range(3)]  # fmt: skip
            # a model change of descent 1, whose reference fit gives the survey covariance:
            # fitted again alone (it was replayed before the covariance was computed at a
            # point no annotation moves), and the same with the state removed (a replay)
            refit = [_run("annotate", session, "--descents", "1", "--model", m)
                     for m in ("velocity", "constant", "velocity")]  # fmt: skip
            replayed = []
            for m in ("constant", "velocity", "constant"):
                os.unlink(os.path.join(session, STATE))
                replayed.append(_run("annotate", session, "--descents", "1", "--model", m))
            lock = RecordingLock.take(session)
            held = [_run("annotate", session, "--descents", "2", "--valid") for _ in range(3)]
            lock.release()
            print(
                f"{n:3d} descents: annotate, the first (replayed) {first:6.2f} s"
                f"   in place {statistics.median(runs) * 1e3:6.1f} ms"
                f"   while recorded (no rewrite) {statistics.median(held) * 1e3:6.1f} ms"
            )
            print(
                f"             descent 1's model: in place {statistics.median(refit) * 1e3:6.1f} ms"
                f"   replayed {statistics.median(replayed):6.2f} s"
            )
            t0 = time.perf_counter()
            for _ in range(1000):
                recording_state(session)
            per = (time.perf_counter() - t0) / 1000
            print(f"             recording_state (try the lock) {per * 1e6:6.1f} µs per session")


if __name__ == "__main__":
    main_()
