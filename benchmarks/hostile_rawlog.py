"""Reading is linear in the size of what is read, however hostile it is (issue 18).

1. The framer fed one chunk without a line end (a runaway line: wrong baud rate, garbage,
   or one 32 MB raw-log record): 2, 8 and 32 MB. Before issue 18 the framer re-sliced the
   rest of the line after every 512-character cut: quadratic, 41 s for 32 MB (the old cut is
   run on 1, 2 and 4 MB for the comparison).
2. A session whose raw log holds that 32 MB record (no line end in it) among a day's records,
   replayed end to end (read_rawlog, processor, descents, fits): seconds.
3. read_rawlog over raw logs of 8 and 32 MB of ordinary records, and over one of 8 MB of bad
   records (each passed over with a warning, 10 named): MB/s and the ratio of the times; and
   read_rawlog_bulk (what ``replay SESSION --no-fit`` reads) over the same.

    python benchmarks/hostile_rawlog.py [--sizes 2,8,32]

Prints the figures and the ratios (linear: time ratio = size ratio).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.session.rawlog import read_rawlog, read_rawlog_bulk  # noqa: E402
from station.timing.framing import LineFramer  # noqa: E402

MB = 1024 * 1024


def time_it(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def framer(sizes: list[int]) -> None:
    print("1. framer, one chunk without a line end")
    base = None
    for mb in sizes:
        data = b"x" * (mb * MB)
        s = time_it(lambda data=data: LineFramer().feed(data))
        base = base or (mb, s)
        ratio = (s / base[1]) / (mb / base[0]) if mb != base[0] else 1.0
        print(f"   {mb:4d} MB: {s:7.3f} s  ({mb / s:7.1f} MB/s; time per MB vs {base[0]} MB: "
              f"{ratio:.2f}x)")  # fmt: skip


def before(sizes: list[int]) -> None:
    """The cut as it was before issue 18, for the ratio (small sizes: it is quadratic)."""
    from station.timing.framing import MAX_LINE

    def old_cut(tail: str) -> list[str]:
        parts = []
        while len(tail) > MAX_LINE:  # the rest copied again after every cut
            parts.append(tail[:MAX_LINE])
            tail = tail[MAX_LINE:]
        return parts

    print("   before issue 18 (the old cut, same input):")
    base = None
    for mb in sizes:
        text = "x" * (mb * MB)
        s = time_it(lambda text=text: old_cut(text))
        base = base or (mb, s)
        ratio = (s / base[1]) / (mb / base[0]) if mb != base[0] else 1.0
        print(f"   {mb:4d} MB: {s:7.3f} s  ({mb / s:7.1f} MB/s; time per MB vs {base[0]} MB: "
              f"{ratio:.2f}x)")  # fmt: skip


def record_line(t: float, rx: str) -> str:
    return json.dumps({"t": t, "rx": rx}, separators=(",", ":")) + "\n"


def day_records(n: int, t0: float) -> list[str]:
    """``n`` ordinary records: ALGE lines a timer sends, a chunk each."""
    out = []
    for i in range(n):
        s = 36_000 + i
        tod = f"{s // 3600:02d}:{s // 60 % 60:02d}:{s % 60:02d}.{i % 10_000:04d}"
        out.append(record_line(t0 + i, f" {i % 10_000:04d} C{i % 9}  {tod} 00\r"))
    return out


def replay_session(tmp: str, mb: int) -> None:
    from station.session import store
    from station.session.config import load_config
    from station.session.runs import replay

    session = os.path.join(tmp, "session")
    cfg = load_config(str(ROOT / "surveys" / "demo_station.yaml"))
    store.create(cfg, session)
    t0 = 1_770_000_000.0
    with open(os.path.join(session, store.RAW), "w") as fh:
        fh.writelines(day_records(200, t0))
        fh.write(record_line(t0 + 300, "x" * (mb * MB)))  # garbage: no line end in 32 MB
        fh.writelines(day_records(200, t0 + 400))
    cfg = store.load_session_config(session)
    warnings: list[str] = []
    holder = {}
    s = time_it(lambda: holder.setdefault("acq", replay(session, cfg, warnings=warnings)))
    acq = holder["acq"]
    counts = acq.line_counts()
    print(
        f"2. replay of a session with a {mb} MB record without a line end: {s:.2f} s "
        f"({counts.lines} lines, {counts.unparsed} unparsed, {len(acq.results())} descents)"
    )


def reading(tmp: str, sizes: list[int]) -> None:
    print("3. read_rawlog (every record checked)")
    line = day_records(1, 1_770_000_000.0)[0]
    first = None
    for mb in sizes:
        path = os.path.join(tmp, f"raw-{mb}.jsonl")
        with open(path, "w") as fh:
            fh.write(line * (mb * MB // len(line)))
        s = time_it(lambda path=path: sum(1 for _ in read_rawlog(path)))
        first = first or (mb, s)
        ratio = (s / first[1]) / (mb / first[0])
        print(f"   {mb:4d} MB of records: {s:6.2f} s ({mb / s:5.1f} MB/s; time per MB vs "
              f"{first[0]} MB: {ratio:.2f}x)")  # fmt: skip
        bulk = time_it(lambda path=path: sum(1 for _ in read_rawlog_bulk(path)))
        print(f"   {mb:4d} MB, read in bulk (replay --no-fit): {bulk:6.2f} s "
              f"({mb / bulk:5.1f} MB/s, {s / bulk:.1f}x faster)")  # fmt: skip
    path = os.path.join(tmp, "bad.jsonl")
    bad = '{"t": NaN, "rx": "\\u20ac"}\n'
    with open(path, "w") as fh:
        fh.write(bad * (sizes[0] * MB // len(bad)))
    warnings: list[str] = []
    s = time_it(lambda: sum(1 for _ in read_rawlog(path, warnings)))
    print(
        f"   {sizes[0]:4d} MB of bad records: {s:6.2f} s ({sizes[0] / s:5.1f} MB/s), "
        f"{len(warnings)} warning lines: {warnings[-1]}"
    )
    bulk_warnings: list[str] = []
    bulk = time_it(lambda: sum(1 for _ in read_rawlog_bulk(path, bulk_warnings)))
    assert bulk_warnings == warnings
    print(f"   {sizes[0]:4d} MB of bad records in bulk: {bulk:6.2f} s ({sizes[0] / bulk:5.1f} "
          "MB/s), the same warnings")  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,8,32", help="MB, comma-separated")
    args = ap.parse_args()
    sizes = [int(x) for x in args.sizes.split(",")]
    framer(sizes)
    before([1, 2, 4])
    with tempfile.TemporaryDirectory(prefix="station-bench-") as tmp:
        replay_session(tmp, sizes[-1])
        reading(tmp, [s for s in sizes if s >= 8] or sizes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
