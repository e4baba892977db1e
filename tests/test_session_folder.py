"""Session folders: never over another session's files, one line for a folder that cannot be
written, a CSV failure that does not end the recording, start times dated by the device."""

from __future__ import annotations

import datetime as dt
import errno
import os
from types import SimpleNamespace

import pandas as pd
import pytest

from station.errors import InputError
from station.session import folder as session_folder
from station.session.analysis import start_time
from station.session.config import load_config
from station.session.results import COLUMNS
from station.timing.impulses import DAY_US
from tests.conftest import DEMO_SURVEY
from tests.timing_helpers import write_config


@pytest.fixture
def cfg(tmp_path):
    return load_config(str(write_config(tmp_path, "loop://")))


def test_a_new_folder_gets_the_snapshot(cfg, tmp_path):
    session = tmp_path / "s"
    session_folder.create(cfg, str(session))
    assert (session / "config.yaml").exists()
    assert any(p.suffix == ".gsi" for p in session.rglob("*"))


@pytest.mark.parametrize("content", ["raw.jsonl", "results.csv", "notes.txt"])
def test_a_folder_with_anything_in_it_is_refused_and_left_alone(cfg, tmp_path, content):
    session = tmp_path / "s"
    session.mkdir()
    (session / content).write_text("someone else's\n")
    with pytest.raises(InputError, match="choose a new --session-dir"):
        session_folder.create(cfg, str(session))
    assert [p.name for p in session.iterdir()] == [content]
    assert (session / content).read_text() == "someone else's\n"


def test_an_empty_folder_is_used(cfg, tmp_path):
    session = tmp_path / "s"
    session.mkdir()
    session_folder.create(cfg, str(session))
    assert (session / "config.yaml").exists()


def test_a_file_is_not_a_session_folder(cfg, tmp_path):
    path = tmp_path / "f"
    path.write_text("x")
    with pytest.raises(InputError, match="is a file, not a folder"):
        session_folder.create(cfg, str(path))


def test_an_unwritable_place_is_one_line(cfg):
    with pytest.raises(InputError) as err:
        session_folder.create(
            cfg, "/sys/station-session-test"
        )  # sysfs: not even root makes folders
    assert "cannot write the session folder" in str(err.value)
    assert "\n" not in str(err.value)


def test_a_full_disk_while_making_the_session_is_one_line_and_leaves_nothing(
    cfg, tmp_path, monkeypatch
):
    import builtins

    real_open = builtins.open

    def full(path, mode="r", *a, **k):
        if "x" in mode or "w" in mode:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_open(path, mode, *a, **k)

    monkeypatch.setattr(builtins, "open", full)
    session = tmp_path / "s"
    with pytest.raises(InputError, match="No space left on device"):
        session_folder.create(cfg, str(session))
    assert not session.exists()


def test_a_results_csv_that_cannot_be_written_is_a_line_not_an_exception(tmp_path, monkeypatch):
    import station.session.results as results

    def full(*_a, **_k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    row = {c: None for c in COLUMNS} | {"descent": 1, "status": "ok"}
    path = tmp_path / "results.csv"

    def write(rows):
        return lambda p: results.write_results(rows, p, {})

    assert session_folder.save_results(str(path), write([row])) is None
    before = path.read_bytes()
    monkeypatch.setattr(results.os, "replace", full)
    problem = session_folder.save_results(str(path), write([row, row | {"descent": 2}]))
    assert problem is not None and "No space left on device" in problem
    assert "raw log keeps recording" in problem and "\n" not in problem
    assert path.read_bytes() == before  # the last good CSV stays
    assert [p.name for p in tmp_path.iterdir()] == ["results.csv"]  # no temp file left


def test_a_hostile_survey_name_keeps_the_csv_readable(tmp_path, run_station):
    survey = tmp_path / "run.yaml"
    (tmp_path / "demo_run.gsi").write_text((DEMO_SURVEY.parent / "demo_run.gsi").read_text())
    text = DEMO_SURVEY.read_text()
    assert "name: Demo run (simulated survey)" in text
    hostile = 'name: "Run,\\r\\n=cmd|x;\\ty"'
    survey.write_text(text.replace("name: Demo run (simulated survey)", hostile))
    cfg = write_config(tmp_path, "loop://")
    cfg.write_text(cfg.read_text().replace(str(DEMO_SURVEY), str(survey)))
    cap = tmp_path / "cap.txt"
    cap.write_bytes(b" 0001 C0  10:00:00.0000 00\r")
    out = tmp_path / "out.csv"
    r = run_station("replay", cap, "--config", cfg, "--csv", out, "--date", "2026-01-02")
    assert r.returncode == 0, r.stderr
    assert "# survey: Run | =cmd|x | y (run.yaml | sha256" in out.read_text()
    df = pd.read_csv(out, comment="#")
    assert list(df.columns) == COLUMNS


def _start(start_us: int, host: dt.datetime | None, date: dt.date | None = None) -> str:
    d = SimpleNamespace(start_us=start_us, day=None)
    host_t = host.timestamp() if host is not None else None
    return start_time(d, host_t, date)[:19]  # type: ignore[arg-type]  # without the UTC offset


def test_start_time_keeps_the_device_day_across_midnight():
    tod = lambda h, m, s: ((h * 60 + m) * 60 + s) * 1_000_000  # noqa: E731
    # started 23:59:58 on the device, finished after midnight on the host: the day it started
    assert _start(tod(23, 59, 58), dt.datetime(2026, 1, 2, 0, 0, 20)) == "2026-01-01T23:59:58"
    assert _start(tod(0, 1, 0), dt.datetime(2026, 1, 2, 0, 1, 30)) == "2026-01-02T00:01:00"
    # a device clock a few minutes ahead of the host, just before midnight on the host
    assert _start(tod(0, 2, 0), dt.datetime(2026, 1, 1, 23, 58, 0)) == "2026-01-02T00:02:00"
    # replay of a capture: the date given plus the device's day count
    assert _start(DAY_US + tod(0, 0, 5), None, dt.date(2026, 1, 1)) == "2026-01-02T00:00:05"
    assert _start(tod(10, 0, 0), None, None) == "10:00:00"


@pytest.mark.parametrize("where", ["file", "sysfs", "other-session"])
def test_record_into_a_bad_session_dir_is_one_line_exit_2(tmp_path, run_station, where):
    cfg = write_config(tmp_path, "loop://")
    if where == "file":
        target = tmp_path / "f"
        target.write_text("x")
    elif where == "sysfs":
        target = "/sys/station-session-test"
    else:
        target = tmp_path / "old"
        target.mkdir()
        (target / "raw.jsonl").write_text("{}\n")
    r = run_station("record", "--config", cfg, "--session-dir", target, "--duration", "1")
    assert r.returncode == 2, r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("station: error")]
    assert len(errors) == 1 and "Traceback" not in r.stderr
