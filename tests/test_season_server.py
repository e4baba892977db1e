"""A team's server: several stations adding at once (no doubles, no loss), and the server
going away in the middle of an add (one line, exit status 2, nothing half-written, the next
add completes it). A real PostgreSQL server, real processes."""

from __future__ import annotations

import datetime as dt
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import sqlalchemy as sa

from station.store import schema
from station.store.db import open_store
from tests.conftest import station_cmd
from tests.season_helpers import PgServer, make_day

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def days(tmp_path_factory) -> list[Path]:
    base = tmp_path_factory.mktemp("days")
    return [
        make_day(base, f"day{d}", dt.date(2026, 1, 1 + d), "ABBAABBA",
                 {"A": 0.01 + 0.001 * d, "B": 0.011 + 0.001 * d}, seed=d)
        for d in range(6)
    ]  # fmt: skip


def _whole(url: str) -> dict[str, int]:
    """Each stored session's descents: as many rows as its session row says."""
    store = open_store(url)
    try:
        with store.reading() as c:
            s, d = schema.sessions, schema.descents
            said = dict(c.execute(sa.select(s.c.name, s.c.descents)).all())
            rows = dict(
                c.execute(
                    sa.select(s.c.name, sa.func.count(d.c.number))
                    .select_from(s.join(d, d.c.session_id == s.c.id))
                    .group_by(s.c.name)
                ).all()
            )
    finally:
        store.close()
    assert said == rows
    return said


def test_stations_adding_at_once_make_no_doubles(days):
    server = PgServer()
    try:
        url = server.url(server.create_db())
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
        procs = [
            subprocess.Popen([*station_cmd(), "season", "add", *map(str, order), "--store", url],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
            for order in (days, days[::-1], days[2:] + days[:2])
        ]  # fmt: skip
        outs = [p.communicate(timeout=600) for p in procs]
        assert all(p.returncode == 0 for p in procs), outs
        verdicts = [line.rsplit(": ", 1)[1] for out, _ in outs for line in out.splitlines()]
        assert verdicts.count("added") == len(days)  # each session added once, by one station
        assert _whole(url) == {d.name: 8 for d in days}
    finally:
        server.close()


def test_the_server_going_away_mid_add(days):
    server = PgServer()
    try:
        url = server.url(server.create_db())
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
        proc = subprocess.Popen(
            [*station_cmd(), "season", "add", *map(str, days), "--store", url],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )  # fmt: skip
        assert proc.stdout is not None
        first = proc.stdout.readline()  # one session is in: the server goes away
        assert first.endswith(": added\n"), first
        stopper = threading.Thread(target=server.stop, args=("immediate",))
        stopper.start()
        out, err = proc.communicate(timeout=300)
        stopper.join()
        assert proc.returncode == 2
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err
        assert "not added" in lines[0] and "add them again" in lines[0]
        server.start()
        stored = _whole(url)  # whatever is stored is whole
        assert 1 <= len(stored) < len(days)
        r = subprocess.run(
            [*station_cmd(), "season", "add", *map(str, days), "--store", url],
            capture_output=True, text=True, env=env, timeout=600,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        assert _whole(url) == {d.name: 8 for d in days}  # the next add completes it
    finally:
        server.close()


def _readme_sql() -> list[tuple[str, str]]:
    """The README's SQL for a team's database, as (database, statement) in order."""
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = text[text.index("## Season store") :]
    block = section[section.index("```sql\n") + 7 :]
    block = block[: block.index("```")]
    out, db, stmt = [], "postgres", ""
    for line in block.splitlines():
        if line.startswith("\\connect "):
            db = line.split()[1]
            continue
        stmt += line + "\n"
        if line.rstrip().endswith(";"):
            out.append((db, stmt.strip()))
            stmt = ""
    return out


def test_the_readme_team_database_with_a_writing_and_a_read_only_role(days):
    server = PgServer()
    try:
        for db, stmt in _readme_sql():
            server.admin(stmt, db)
        pw = {"season_owner": "change-me-owner", "station": "change-me-station",
              "coach": "change-me-coach"}  # fmt: skip
        url = {role: server.url("season", pw[role], role) for role in pw}
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}

        def season(*args: str, role: str) -> subprocess.CompletedProcess:
            return subprocess.run([*station_cmd(), "season", *args, "--store", url[role]],
                                  capture_output=True, text=True, env=env, timeout=300)  # fmt: skip

        r = season("add", str(days[0]), role="season_owner")  # the owner makes the tables
        assert r.returncode == 0, r.stderr
        r = season("add", str(days[1]), str(days[2]), role="station")
        assert r.returncode == 0, r.stderr
        r = season("list", "--json", role="coach")
        assert r.returncode == 0, r.stderr
        assert '"day2"' in r.stdout
        r = season("add", str(days[3]), role="coach")
        assert r.returncode == 2
        assert len(r.stderr.strip().splitlines()) == 1 and "permission denied" in r.stderr
        assert "change-me" not in r.stderr
    finally:
        server.close()
