"""``station sessions DIR`` survives its worst member (issue 18, item 5): a raw log that is a
FIFO or a link to /dev/zero, a binary results CSV. The bad session is listed as broken with the
reason, the others as usual; the listing never hangs (each command runs in a process of its own
with a time limit, so a hang fails the test instead of stalling the suite)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from station.session import folder as session_folder
from tests.conftest import ROOT
from tests.session_helpers import make_session

#: far above the listing's own time (a second or two), far below a hang
LIMIT_S = 60


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    return make_session(tmp_path_factory.mktemp("day"), order="AB")


def sessions(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "station", "sessions", *map(str, args)],
        capture_output=True, text=True, timeout=LIMIT_S, cwd=ROOT, env=env,
    )  # fmt: skip


def two_sessions(recorded, tmp_path):
    """A folder with a good session ``a-good`` and a copy ``b-bad`` to be damaged."""
    folder = tmp_path / "sessions"
    folder.mkdir()
    shutil.copytree(recorded, folder / "a-good")
    shutil.copytree(recorded, folder / "b-bad")
    return folder, folder / "b-bad"


def check_listing(folder, why: str) -> None:
    r = sessions(folder, "--json")
    assert r.returncode == 0, r.stderr
    rows = {os.path.basename(x["path"]): x for x in json.loads(r.stdout)}
    good, bad = rows["a-good"], rows["b-bad"]
    assert good["status"] == "finished" and good["descents"] == 2 and "problem" not in good
    assert bad["status"] == "broken" and why in bad["problem"], bad
    warned = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(warned) == 1 and "b-bad" in warned[0] and why in warned[0], r.stderr
    assert "Traceback" not in r.stderr
    r = sessions(folder)  # the table too
    assert r.returncode == 0, r.stderr
    lines = {ln.split()[0]: ln for ln in r.stdout.splitlines()[1:]}
    assert "finished" in lines[str(folder / "a-good")]
    assert "broken" in lines[str(folder / "b-bad")] and why in lines[str(folder / "b-bad")]


def test_a_raw_log_that_is_a_fifo_is_broken_not_a_hang(recorded, tmp_path):
    folder, bad = two_sessions(recorded, tmp_path)
    (bad / session_folder.RAW).unlink()
    os.mkfifo(bad / session_folder.RAW)
    check_listing(folder, "is a pipe (FIFO), not a raw log")


def test_a_raw_log_linked_to_dev_zero_is_broken_not_a_hang(recorded, tmp_path):
    folder, bad = two_sessions(recorded, tmp_path)
    (bad / session_folder.RAW).unlink()
    os.symlink("/dev/zero", bad / session_folder.RAW)
    check_listing(folder, "is a character device, not a raw log")


def test_a_binary_results_csv_is_broken_with_the_reason(recorded, tmp_path):
    folder, bad = two_sessions(recorded, tmp_path)
    (bad / session_folder.RESULTS).write_bytes(b"\x00\xff\xfe" + os.urandom(2000))
    check_listing(folder, "results.csv")


def test_a_results_csv_with_text_in_a_number_column_names_line_and_column(recorded, tmp_path):
    folder, bad = two_sessions(recorded, tmp_path)
    text = (bad / session_folder.RESULTS).read_text().splitlines()
    head = next(i for i, ln in enumerate(text) if ln.startswith('"descent"'))
    text[head + 2] = "x" + text[head + 2]  # descent 2's number: "x2"
    (bad / session_folder.RESULTS).write_text("\n".join(text) + "\n")
    check_listing(folder, f"results.csv:{head + 3}: field descent: 'x2' is not a whole number")


def test_a_recording_lock_that_is_a_fifo_does_not_hang_the_listing(recorded, tmp_path):
    folder, bad = two_sessions(recorded, tmp_path)
    os.mkfifo(bad / session_folder.LOCK)
    r = sessions(folder, "--json")
    assert r.returncode == 0, r.stderr
    assert len(json.loads(r.stdout)) == 2


def test_only_broken_sessions_is_exit_status_2_and_no_sessions_is_0(recorded, tmp_path):
    folder, bad = two_sessions(recorded, tmp_path)
    shutil.rmtree(folder / "a-good")
    (bad / session_folder.RESULTS).write_bytes(b"\x00" * 100)
    r = sessions(folder)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "station: error:" in r.stderr and "broken" in r.stdout
    shutil.rmtree(bad)
    r = sessions(folder)
    assert r.returncode == 0 and "no sessions" in r.stdout


def test_an_imported_session_is_listed_by_its_test_day_not_by_the_import(
    tmp_path, demo_track, run_station
):
    """A download imported days later was listed as started at the import (its raw log's first
    record): now by its first descent's start, the import's time said beside it."""
    import datetime as dt

    from tests.test_memory_import import _alge_capture
    from tests.timing_helpers import write_config

    cfg = write_config(tmp_path, "/dev/null")
    cap = _alge_capture(tmp_path / "day.txt", demo_track, 36_000)
    folder = tmp_path / "sessions"
    r = run_station("import", cap, "--config", cfg, "--session-dir", folder / "imp",
                    "--date", "2026-01-12")  # fmt: skip
    assert r.returncode == 0, r.stderr
    today = dt.date.today().isoformat()
    r = sessions(folder, "--json")
    assert r.returncode == 0, r.stderr
    (row,) = json.loads(r.stdout)
    assert row["started"] == "2026-01-12 10:00", row
    assert row["imported"].startswith(today), row
    r = sessions(folder)
    line = r.stdout.splitlines()[1]
    assert "2026-01-12 10:00" in line and f"imported {today}" in line, r.stdout
