"""The first ``station annotate`` after a recording (issue 19): a recording that ends cleanly
writes the results state a replay would (station/session/acquisition.py, ``close``), so the
annotate changes rows in place instead of replaying the day.

A day of N descents is made as tests/session_helpers.py makes them, then recorded by the
recorder's own loop (threads, fit worker, results CSV, raw log) fed its chunks as the serial
reader feeds them (tests/test_record_state.py does the same). Printed: the recorder's
``close`` with the state written (and the part of it that writes the state), the first
annotate (one invalid mark) in place, and the same annotate with the state removed first
(the station before this change: the day replayed, its fits from the store).

Run: python benchmarks/record_state.py [--sizes 200,2000]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.session import store  # noqa: E402
from station.session.acquisition import Acquisition  # noqa: E402
from station.session.listener import QuietListener  # noqa: E402
from station.session.recorded_session import RecordedSession  # noqa: E402
from station.session.records import InvalidMark  # noqa: E402
from station.session.replay import replay_chunks  # noqa: E402
from station.session.resultsstate import STATE  # noqa: E402
from tests.session_helpers import make_session  # noqa: E402


def measure(n: int, tmp: Path) -> dict[str, float]:
    (tmp / "src").mkdir()
    source = make_session(tmp / "src", order="AB" * (n // 2), interval_s=20.0, annotate=False)
    session = tmp / "rec"
    cfg = store.load_session_config(str(source))
    acq = Acquisition.open(cfg, QuietListener(), session_dir=str(session))
    for chunk in replay_chunks(str(source), None, threading.Event(), []):
        if chunk.event != "session":
            acq.receive(chunk)
    state_s = [0.0]
    write_state = acq._write_results_state  # noqa: SLF001 - timed apart

    def timed() -> None:
        t = time.perf_counter()
        write_state()
        state_s[0] = time.perf_counter() - t

    acq._write_results_state = timed  # type: ignore[method-assign]  # noqa: SLF001
    t0 = time.perf_counter()
    acq.close()
    close_s = time.perf_counter() - t0
    assert (session / STATE).exists(), acq.not_as_replayed
    copy = tmp / "copy"
    shutil.copytree(session, copy)
    os.unlink(copy / STATE)
    t0 = time.perf_counter()
    RecordedSession(str(session)).annotate([InvalidMark(2, "fell", 2.0)])
    in_place = time.perf_counter() - t0
    t0 = time.perf_counter()
    RecordedSession(str(copy)).annotate([InvalidMark(2, "fell", 2.0)])
    replayed = time.perf_counter() - t0
    return {"close": close_s, "state": state_s[0], "in place": in_place, "replayed": replayed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="200,2000")
    args = ap.parse_args()
    print(f"{'descents':>8} {'close':>9} {'of it state':>12} {'annotate':>9} "
          f"{'replayed':>9} {'ratio':>7}")  # fmt: skip
    for n in (int(x) for x in args.sizes.split(",")):
        with tempfile.TemporaryDirectory() as tmp:
            f = measure(n, Path(tmp))
        print(f"{n:>8} {f['close'] * 1e3:>7.1f}ms {f['state'] * 1e3:>10.1f}ms "
              f"{f['in place'] * 1e3:>7.1f}ms {f['replayed'] * 1e3:>7.0f}ms "
              f"{f['replayed'] / f['in place']:>6.0f}×")  # fmt: skip


if __name__ == "__main__":
    main()
