"""The recorded session object (station/session/recorded_session.py): what each command used to put
together by itself, checked once here against the files it stands for."""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import shutil

import pytest

from station import __version__
from station.errors import InputError
from station.session import folder as session_folder
from station.session.recorded_session import RecordedSession
from station.session.records import InvalidMark, Metadata, MetadataAnnotation
from tests.session_helpers import T0, make_session


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    return make_session(tmp_path_factory.mktemp("day"), order="ABBA")


@pytest.fixture
def session(recorded, tmp_path):
    copy = tmp_path / "session"
    shutil.copytree(recorded, copy)
    return copy


def test_a_folder_without_a_raw_log_is_not_a_session(tmp_path):
    with pytest.raises(InputError, match="not a session directory"):
        RecordedSession(str(tmp_path))


def test_provenance_is_the_files_hashes_the_version_and_the_raw_logs_first_and_last_time(
    session,
):
    p = RecordedSession(str(session)).provenance()
    cfg = session_folder.load_session_config(str(session))
    assert p.raw_sha256 == hashlib.sha256((session / session_folder.RAW).read_bytes()).hexdigest()
    assert (
        p.config_sha256
        == hashlib.sha256((session / session_folder.CONFIG).read_bytes()).hexdigest()
    )
    with open(cfg.survey_path, "rb") as fh:
        assert p.survey_sha256 == hashlib.sha256(fh.read()).hexdigest()
    assert p.station_version == __version__
    records = [json.loads(x) for x in (session / session_folder.RAW).read_text().splitlines()]
    assert p.first_host_time == records[0]["t"] == T0 - 60.0
    assert p.last_host_time == records[-1]["t"] > p.first_host_time
    # the results CSV's header names the same files by the beginning of the same hashes
    header = session_folder.results_header(cfg, "x")
    assert p.config_sha256[:12] in header["config"] and p.survey_sha256[:12] in header["survey"]


def test_started_is_the_first_records_local_time(session):
    started = RecordedSession(str(session)).started()
    assert started == dt.datetime.fromtimestamp(T0 - 60.0).strftime("%Y-%m-%d %H:%M")


def test_results_are_the_replay_with_the_annotations_and_the_csv_rows_agree(session):
    s = RecordedSession(str(session))
    results = s.results()
    assert [r.number for r in results] == [1, 2, 3, 4] == s.descent_numbers()
    assert [r.row.ski for r in results] == ["pair A", "pair B", "pair B", "pair A"]
    rows = s.rows()
    assert [(r.descent, r.ski, r.wax, r.invalid_reason) for r in rows] == [
        (1, "pair A", "blue", ""), (2, "pair B", "blue", ""),
        (3, "pair B", "blue", ""), (4, "pair A", "blue", ""),
    ]  # fmt: skip
    assert s.run() is s.run()  # replayed once


def test_rows_show_annotations_appended_after_the_csv_without_a_replay(session):
    session_folder.append_annotation(str(session), InvalidMark(3, "fell", 0.0))
    session_folder.append_annotation(
        str(session), MetadataAnnotation(Metadata(ski="pair C"), descents=(4,), t=0.0)
    )
    s = RecordedSession(str(session))
    rows = s.rows()
    assert [r.invalid_reason for r in rows] == ["", "", "fell", ""]
    assert rows[3].ski == "pair C"
    assert s._run is None  # the listing needs no replay


def test_annotate_appends_and_rewrites_the_csv_as_export_writes_it(session, tmp_path):
    s = RecordedSession(str(session))
    before = s.results()
    said = s.annotate([InvalidMark(2, "gate", 1.0)])
    assert said.endswith(f"{session / session_folder.RESULTS} rewritten")
    assert "1 annotation added" in said
    assert [r.row.invalid_reason for r in s.results()] == ["", "gate", "", ""]
    assert before[1].row.invalid_reason == ""  # the earlier replay's snapshot is unchanged
    fresh = RecordedSession(str(session))
    out = tmp_path / "export.csv"
    with open(out, "w", encoding="utf-8", newline="") as fh:
        fresh.write_results_to(fh)
    assert out.read_bytes() == (session / session_folder.RESULTS).read_bytes()


def test_annotate_leaves_the_csv_to_a_recorder_holding_the_session(session):
    before = (session / session_folder.RESULTS).read_bytes()
    lock = session_folder.RecordingLock.take(str(session))
    try:
        said = RecordedSession(str(session)).annotate([InvalidMark(2, "gate", 1.0)])
    finally:
        lock.release()
    assert "being recorded now" in said
    assert (session / session_folder.RESULTS).read_bytes() == before


def test_check_descents_refuses_a_descent_the_session_does_not_have(session):
    s = RecordedSession(str(session))
    s.check_descents([1, 4])
    with pytest.raises(InputError, match=r"no descent 9 in this session \(it has descents 1–4\)"):
        s.check_descents([1, 9])


def test_compare_is_the_days_joint_fit_of_its_items(session):
    day = RecordedSession(str(session)).compare(reference="pair A / blue")
    assert day.result is not None and day.error == ""
    assert {d.item for d in day.compared} == {"pair A / blue", "pair B / blue"}
    assert day.result.reference == "pair A / blue"
    assert len(day.compared) == 4 and not day.result.excluded


def test_compare_says_why_when_there_is_nothing_to_compare(session):
    s = RecordedSession(str(session))
    s.annotate([InvalidMark(n, "all out", 1.0) for n in (1, 2, 3, 4)])
    day = s.compare()
    assert day.result is None and day.error and day.compared == []
