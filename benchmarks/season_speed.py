"""Speed of the season store: adding test days (12 descents each: a replay of the raw log with
its annotations, the day fits, one transaction) and comparing items across them, for 10, 100
and 1000 days, on an SQLite file and, with --postgresql, on a private PostgreSQL server started
from the installed binaries.

Targets (issue 20): adding 100 days ≤ 30 s, ``season compare`` over 100 days ≤ 3 s, both linear
in the days. The days are made once (the model's own times as a timer's lines in a raw log, with
items and snow conditions annotated) and kept in --cache; the first run spends most of its time
making them. Adding N days is timed in one process (``add_sessions``, as ``station season add``
runs), so it is the work per day, not the import of the station (printed separately).

The comparison over 1000 days is timed on the largest store's days copied (--copies 10), so
it needs no 1000 replays; ``--days 10,100,1000`` adds 1000 days too (about five minutes of CPU).

Run: python benchmarks/season_speed.py [--days 10,100] [--copies 10] [--postgresql]
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.season_helpers import PgServer, make_day  # noqa: E402

THETA = {"A": 0.0, "B": 0.0010, "C": -0.0005, "D": 0.0003, "E": 0.0006, "F": -0.0002}
SNOW = ("PP", "DF", "RG", "FC", "MF")


def make_days(cache: Path, n: int) -> list[str]:
    """``n`` test days (made once, kept in ``cache``): two or three skis each, ABBA order."""
    rng = np.random.default_rng(20)
    items = list(THETA)
    out = []
    for d in range(n):
        name = f"day{d:04d}"
        k = 2 + d % 2
        its = [str(x) for x in rng.choice(items, size=k, replace=False)]
        temp = float(np.round(rng.uniform(-16, -1), 1))
        order = "".join(its + its[::-1]) * (12 // (2 * k))
        path = cache / name
        out.append(str(path))
        if (path / "raw.jsonl").exists():
            continue
        level = 0.02 + 0.0008 * temp
        make_day(
            cache, name, dt.date(2025, 11, 1) + dt.timedelta(days=d), order,
            {x: level + THETA[x] + rng.normal(0, 0.0002) for x in its},
            items={x: {"ski": f"S{x}", "wax": "blue"} for x in its},
            conditions={"snow_temperature_c": temp, "snow_type": SNOW[d % len(SNOW)]},
            seed=d,
        )  # fmt: skip
    return out


def timed_add(target: str, days: list[str]) -> tuple[float, float]:
    from station.cli.season import add_sessions
    from station.store.db import open_store

    store = open_store(target, create=True)
    try:
        t, c = time.perf_counter(), time.process_time()
        status = add_sessions(store, days, out=lambda _m: None)
        dt_s, cpu_s = time.perf_counter() - t, time.process_time() - c
    finally:
        store.close()
    assert status == 0
    return dt_s, cpu_s


def timed_compare(target: str) -> tuple[float, int]:
    import argparse as ap

    from station.cli.season import season_comparison
    from station.store.db import open_store

    args = ap.Namespace(by="item", reference=None, at=None, where=None)
    store = open_store(target)
    try:
        t = time.perf_counter()
        res = season_comparison(args, store).result
        args.at = ["snow_temperature_c=-8"]
        season_comparison(args, store)
        dt_s = (time.perf_counter() - t) / 2
    finally:
        store.close()
    return dt_s, res.days


def copied_store(source: str, target: str, times: int) -> int:
    """A store with every stored day of ``source`` copied ``times`` times (new ids): the
    comparison's cost at 1000 days without replaying 1000 days."""
    from station.store import schema
    from station.store.db import open_store
    from station.store.writer import load_record, write_record

    src, dst = open_store(source), open_store(target, create=True)
    try:
        with src.reading() as conn:
            ids = [r[0] for r in conn.execute(schema.sessions.select().with_only_columns(
                schema.sessions.c.id))]  # fmt: skip
            records = [load_record(conn, i) for i in ids]
        n = 0
        with dst.writing() as conn:
            for k in range(times):
                for rec in records:
                    sid = f"{rec.identity.id[:56]}{k:08d}"
                    rec.identity = type(rec.identity)(sid, rec.identity.content_sha256)
                    rec.session = {**rec.session, "id": sid, "name": f"{rec.session['name']}-{k}"}
                    for rows in (rec.descents, rec.annotations, rec.conditions, rec.day_fits,
                                 rec.items, rec.covariances):  # fmt: skip
                        for row in rows:
                            row["session_id"] = sid
                    write_record(conn, rec)
                    n += 1
    finally:
        src.close()
        dst.close()
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--days", default="10,100")
    ap.add_argument(
        "--copies",
        type=int,
        default=10,
        help="compare over the largest store copied this many times (1000 days)",
    )
    ap.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "station-season-days"))
    ap.add_argument("--postgresql", action="store_true", help="also on a PostgreSQL server")
    args = ap.parse_args()
    sizes = [int(x) for x in args.days.split(",")]
    cache = Path(args.cache)
    t = time.perf_counter()
    import station.cli.season  # noqa: F401
    import station.model.compare  # noqa: F401
    import station.store.ingest  # noqa: F401

    print(f"imports: {time.perf_counter() - t:.2f} s (once per command)")
    t = time.perf_counter()
    days = make_days(cache, max(sizes))
    print(f"{max(sizes)} days ready in {cache} ({time.perf_counter() - t:.1f} s)")
    engines = ["sqlite"] + (["postgresql"] if args.postgresql else [])
    server = PgServer() if args.postgresql else None
    try:
        print(f"{'engine':<11}{'days':>6}{'add s':>9}{'s/day':>8}{'add CPU s':>10}"
              f"{'compare s':>11}{'compare ms/day':>16}")  # fmt: skip
        for engine in engines:
            for n in sizes:
                if engine == "sqlite":
                    target = os.path.join(tempfile.mkdtemp(), "season.db")
                else:
                    assert server is not None
                    target = server.url(server.create_db())
                add_s, cpu_s = timed_add(target, days[:n])
                cmp_s, n_days = timed_compare(target)
                print(f"{engine:<11}{n:>6}{add_s:>9.2f}{add_s / n:>8.3f}{cpu_s:>10.2f}"
                      f"{cmp_s:>11.3f}{1000 * cmp_s / n_days:>16.2f}")  # fmt: skip
        if args.copies > 1:
            big = os.path.join(tempfile.mkdtemp(), "copies.db")
            n = copied_store(target, big, args.copies)
            cmp_s, n_days = timed_compare(big)
            print(f"{'sqlite':<11}{n:>6}{'(copies of the days above)':>27}"
                  f"{cmp_s:>11.3f}{1000 * cmp_s / n_days:>16.2f}")  # fmt: skip
    finally:
        if server is not None:
            server.close()
    print("targets: add 100 days <= 30 s; compare over 100 days <= 3 s (on a busy machine the "
          "CPU time is what an idle one would take)")  # fmt: skip
    print(f"load average: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
