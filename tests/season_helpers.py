"""Helpers of the season store's tests and benchmarks: test days made in a fraction of a second
(the model's own times as a timer's lines in a raw log, with annotations for the items and the
snow), and a real PostgreSQL server started from the installed binaries (Debian's `postgresql`
package: initdb and pg_ctl under /usr/lib/postgresql/<version>/bin), in a temporary folder,
reached over a unix socket, with password authentication."""

from __future__ import annotations

import contextlib
import datetime as dt
import glob
import json
import os
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tests.timing_helpers import ALGE_CHANNELS, write_config

PG_USER = "season_admin"
PG_PASSWORD = "s3cret-'pw\""  # quotes: the URL and the server must take it as it is


def make_day(
    base: Path,
    name: str,
    day: dt.date,
    order: str,
    mus: Mapping[str, float],
    items: Mapping[str, Mapping[str, Any]] | None = None,
    conditions: Mapping[str, Any] | None = None,
    cda: float = 0.22,
    posture_sd: float = 0.01,
    noise_ms: float = 0.3,
    seed: int = 1,
    interval_s: float = 240.0,
) -> Path:
    """A session folder ``base/name`` of ``len(order)`` descents of items A, B … with the
    true ``mus``; ``items`` the metadata of each item (default ``ski: pair X``), ``conditions``
    the snow and air of the day (annotated from descent 1 on)."""
    from station.model.physics import Conditions, Params, StraightRun
    from station.session import folder as session_folder
    from station.session.config import load_config
    from station.session.rawlog import RawLogWriter
    from station.session.records import Metadata, MetadataAnnotation
    from station.survey.load import load_survey
    from station.survey.track import build_track
    from station.timing.wireformats import format_alge

    base.mkdir(parents=True, exist_ok=True)
    cfg_path = base / "station.yaml"
    if not cfg_path.exists():
        write_config(base, "/dev/ttyUSB0")
    session = base / name
    cfg = load_config(str(cfg_path))
    session_folder.create(cfg, str(session))
    track = _track(cfg.survey_path, build_track, load_survey)
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    rng = np.random.default_rng(seed)
    t0 = dt.datetime(day.year, day.month, day.day, 10, 0).timestamp()
    log = RawLogWriter(str(session / session_folder.RAW), header={"port": "/dev/ttyUSB0"})
    bib = 0
    for k, item in enumerate(order):
        t_start = t0 + k * interval_s
        sol = run.solve(
            Params(cda * float(np.exp(posture_sd * rng.standard_normal())), mus[item],
                   3.0 + 0.3 * rng.standard_normal()),
            Conditions(88.0, 1.079),
            sensitivities=False,
        )  # fmt: skip
        times = sol.t + np.r_[0.0, rng.normal(0, noise_ms * 1e-3, len(sol.t) - 1)]
        start = dt.datetime.fromtimestamp(t_start)
        tod0 = (start.hour * 3600 + start.minute * 60 + start.second) * 10**6
        for ch, t in zip(ALGE_CHANNELS, times, strict=True):
            bib += 1
            line = format_alge(ch, tod0 + int(round(t * 1e6)), bib)
            log.write(t_start + float(t) + 0.01, (line + "\r").encode("ascii"))
    log.close()
    raw = session / session_folder.RAW  # as if recorded that day
    lines = raw.read_text().splitlines()
    lines[0] = json.dumps({**json.loads(lines[0]), "t": t0 - 60.0}, separators=(",", ":"))
    raw.write_text("\n".join(lines) + "\n")
    if conditions:
        session_folder.append_annotation(
            str(session),
            MetadataAnnotation(Metadata.from_values(conditions), from_descent=1, t=t0),
        )
    for item in sorted(set(order)):
        numbers = tuple(k + 1 for k, it in enumerate(order) if it == item)
        meta = dict((items or {}).get(item, {"ski": f"pair {item}", "wax": "blue"}))
        session_folder.append_annotation(
            str(session),
            MetadataAnnotation(Metadata.from_values(meta), descents=numbers, t=t0),
        )
    return session


_TRACKS: dict[str, Any] = {}


def _track(path: str, build_track: Any, load_survey: Any) -> Any:
    if path not in _TRACKS:
        _TRACKS[path] = build_track(load_survey(path))
    return _TRACKS[path]


# ----------------------------------------------------------------------------- PostgreSQL


def pg_bindir() -> str | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"))
    if found:
        return os.path.dirname(found[-1])
    exe = shutil.which("pg_ctl")
    return os.path.dirname(exe) if exe else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class PgServer:
    """A private PostgreSQL server: ``url(db)`` names a database on it, ``create_db`` makes one,
    ``stop``/``start`` take it away and bring it back (the server going away mid-add)."""

    def __init__(self) -> None:
        bindir = pg_bindir()
        if bindir is None:
            why = ("PostgreSQL's binaries are not installed (apt-get install postgresql): the "
                   "season store's tests run on a real server")  # fmt: skip
            if os.environ.get("CI"):  # CI installs it (.ci/run): missing there is a failure
                raise RuntimeError(why)
            import pytest

            pytest.skip(why)
        self.bindir = bindir
        self.root = tempfile.mkdtemp(prefix="station-pg-")
        self.data = os.path.join(self.root, "data")
        self.sock = os.path.join(self.root, "sock")
        os.makedirs(self.sock)
        self.port = _free_port()
        self.as_user: list[str] = []
        if os.geteuid() == 0:  # the server refuses to run as root
            self.as_user = ["runuser", "-u", "postgres", "--"]
            shutil.chown(self.root, "postgres")
            shutil.chown(self.sock, "postgres")
            os.chmod(self.root, 0o755)
        pwfile = os.path.join(self.root, "pw")
        with open(pwfile, "w") as fh:
            fh.write(PG_PASSWORD + "\n")
        if self.as_user:
            shutil.chown(pwfile, "postgres")
        self._run("initdb", "-D", self.data, "-U", PG_USER, f"--pwfile={pwfile}",
                  "-A", "scram-sha-256", "-E", "UTF8", "--no-instructions")  # fmt: skip
        self.start()
        self.n = 0

    def _run(self, exe: str, *args: str) -> None:
        subprocess.run([*self.as_user, os.path.join(self.bindir, exe), *args], check=True,
                       capture_output=True, timeout=120)  # fmt: skip

    def start(self) -> None:
        opts = f"-k {self.sock} -c listen_addresses='' -p {self.port} -c fsync=off"
        self._run("pg_ctl", "-D", self.data, "-o", opts, "-l",
                  os.path.join(self.root, "log"), "-w", "start")  # fmt: skip

    def stop(self, mode: str = "fast") -> None:
        self._run("pg_ctl", "-D", self.data, "-m", mode, "-w", "stop")

    def url(self, db: str, password: str = PG_PASSWORD, user: str = PG_USER) -> str:
        from urllib.parse import quote

        return (f"postgresql://{user}:{quote(password, safe='')}@/{db}"
                f"?host={self.sock}&port={self.port}")  # fmt: skip

    def admin(self, sql: str, db: str = "postgres") -> None:
        import psycopg

        with psycopg.connect(
            host=self.sock,
            port=self.port,
            user=PG_USER,
            password=PG_PASSWORD,
            dbname=db,
            autocommit=True,
        ) as c:
            c.execute(sql)  # fmt: skip

    def create_db(self) -> str:
        self.n += 1
        name = f"season_{self.n}"
        self.admin(f"CREATE DATABASE {name}")
        return name

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.stop("immediate")
        shutil.rmtree(self.root, ignore_errors=True)


@contextlib.contextmanager
def pg_server() -> Iterator[PgServer]:
    server = PgServer()
    try:
        yield server
    finally:
        server.close()
