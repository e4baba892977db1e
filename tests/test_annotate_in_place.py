"""``station annotate`` without a replay (issue 19): an annotation that changes no fit changes
the rows of results.csv it concerns in place (station/session/resultsfile.py), and the file
is byte for byte what a replay of the session from scratch writes; one that changes a fit, or
a results CSV that is not the one its state describes, is replayed as before."""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from station.session import folder as session_folder
from station.session.recorded_session import RecordedSession
from station.session.records import (
    Annotation,
    FitModel,
    InvalidMark,
    Metadata,
    MetadataAnnotation,
    ModelChange,
    ValidMark,
)
from station.session.resultsstate import STATE
from station.session.runs import replay
from tests.session_helpers import make_session

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Six descents, annotated once by ``RecordedSession.annotate`` (a replay: the CSV had no
    state yet), which leaves the CSV and its state."""
    session = make_session(tmp_path_factory.mktemp("day"), order="ABBAAB")
    said = RecordedSession(str(session)).annotate(
        [MetadataAnnotation(Metadata(notes="morning"), from_descent=1, t=1.0)]
    )
    assert said.endswith("rewritten") and (session / STATE).exists()
    return session


@pytest.fixture
def session(recorded, tmp_path):
    copy = tmp_path / "session"
    shutil.copytree(recorded, copy)
    return copy


def from_scratch(session: Path) -> bytes:
    """The results CSV of a replay of the session with every fit computed (no stored fit,
    no state), as ``station export`` writes it."""
    cfg = session_folder.load_session_config(str(session))
    acq = replay(str(session), cfg, speed_curves=False)
    out = io.StringIO(newline="")
    acq.write_csv_to(out)
    return out.getvalue().encode("utf-8")


def csv_of(session: Path) -> bytes:
    return (session / session_folder.RESULTS).read_bytes()


NOTES = 'line one\nline two, "quoted"; =not a formula'

#: steps of annotations, each one ``station annotate``, and whether it is done in place
KINDS: dict[str, list[tuple[list[Annotation], bool]]] = {
    "invalid": [([InvalidMark(2, "fell at gate 3", 2.0)], True)],
    "invalid, then valid again": [
        ([InvalidMark(2, "fell", 2.0)], True),
        ([ValidMark(2, 3.0)], True),
    ],
    "invalid twice, a reason that looks like a formula": [
        ([InvalidMark(3, "gate", 2.0)], True),
        ([InvalidMark(3, "=cmd|' /C calc'!A0", 3.0), InvalidMark(5, "", 3.0)], True),
    ],
    "metadata from a descent on": [
        ([MetadataAnnotation(Metadata(ski="pair C", notes=NOTES), from_descent=4, t=2.0)], True),
    ],
    "metadata for listed descents": [
        (
            [
                MetadataAnnotation(
                    Metadata(wax="red", snow_temperature_c=-4.5, skier="-B"), descents=(2, 5), t=2.0
                )
            ],
            True,
        ),  # fmt: skip
    ],
    "a listed descent keeps its metadata over a later change from N on": [
        ([MetadataAnnotation(Metadata(ski="pair X"), descents=(4,), t=2.0)], True),
        ([MetadataAnnotation(Metadata(ski="pair Y"), from_descent=3, t=3.0)], True),
        ([InvalidMark(4, "wind", 4.0)], True),
    ],
    "metadata without a column (grind, snow type)": [
        ([MetadataAnnotation(Metadata(grind="S1", snow_type="MM"), descents=(1,), t=2.0)], True),
    ],
    "a descent still to come": [
        ([MetadataAnnotation(Metadata(wax="green"), from_descent=99, t=2.0)], True),
    ],
    "a model change (the descent alone fitted again)": [
        ([InvalidMark(3, "fell", 2.0)], True),
        ([ModelChange(3, FitModel.VELOCITY, 3.0)], True),
        ([ValidMark(3, 4.0)], True),
        ([ModelChange(3, FitModel.CONSTANT, 5.0), InvalidMark(4, "gate", 5.0)], True),
    ],
    # the survey covariance the later fits take is computed at descent 1's reference fit,
    # which no annotation moves: descent 1 is fitted again alone (it used to be replayed)
    "a model change of the first descent, whose reference fit gives the survey covariance": [
        ([ModelChange(1, FitModel.VELOCITY, 2.0)], True),
        ([InvalidMark(1, "gate", 3.0)], True),
        ([MetadataAnnotation(Metadata(mass_kg=70.0), descents=(1, 2), t=4.0)], True),
    ],
    "a mass and a ski for listed descents": [
        ([MetadataAnnotation(Metadata(mass_kg=70.0, ski="light"), descents=(5,), t=2.0)], True),
        ([InvalidMark(5, "too light", 3.0)], True),
        (
            [
                MetadataAnnotation(
                    Metadata(pressure_hpa=850.0, air_temperature_c=-8.0), descents=(2, 6), t=4.0
                )
            ],
            True,
        ),  # fmt: skip
    ],
    "a mass from a descent on": [
        ([MetadataAnnotation(Metadata(mass_kg=80.0), from_descent=4, t=2.0)], False),
        ([InvalidMark(5, "fell", 3.0)], True),
    ],
    "a wind without a direction for a listed descent (an error row)": [
        ([MetadataAnnotation(Metadata(wind_ms=2.0), descents=(4,), t=2.0)], True),
    ],
}


@pytest.mark.parametrize("kind", list(KINDS))
def test_an_annotation_in_place_writes_what_a_replay_from_scratch_writes(session, replays, kind):
    for records, in_place in KINDS[kind]:
        replays.clear()
        said = RecordedSession(str(session)).annotate(records)
        assert said.endswith(f"{session / session_folder.RESULTS} rewritten")
        assert (replays == []) is in_place, (records, replays)
        assert csv_of(session) == from_scratch(session), records


def poor_first_descent(session: Path) -> None:
    """Descent 1's third crossing 5 ms late (the same size): its fit is poor (χ² against the
    timer's 0.5 ms), so descent 2's reference fit gives its photocells the survey covariance,
    and descent 1's fit computes its own."""
    raw = session / session_folder.RAW
    lines = raw.read_text().splitlines(keepends=True)
    rec = json.loads(lines[3])
    assert rec["rx"] == " 0003 C2  10:00:07.0310 00\r", rec  # make_session's seed 1
    rec["rx"] = " 0003 C2  10:00:07.0360 00\r"
    lines[3] = json.dumps(rec, separators=(",", ":")) + "\n"
    raw.write_text("".join(lines))


@pytest.fixture(scope="module")
def poor_first(tmp_path_factory):
    """Six descents, the first a poor fit (:func:`poor_first_descent`), annotated once by a
    replay, which leaves the CSV and its state."""
    session = make_session(tmp_path_factory.mktemp("day"), order="ABBAAB")
    poor_first_descent(session)
    RecordedSession(str(session)).annotate([InvalidMark(6, "gate", 1.0)])
    return session


BEFORE_THE_SOURCE = {
    "a model change of the descent before it": [ModelChange(1, FitModel.VELOCITY, 2.0)],
    "a model change of the descent that gives it": [ModelChange(2, FitModel.VELOCITY, 2.0)],
    "a mass for both and a later one": [
        MetadataAnnotation(Metadata(mass_kg=75.0), descents=(1, 2, 5), t=2.0)
    ],
}


@pytest.mark.parametrize("kind", list(BEFORE_THE_SOURCE))
def test_a_descent_fitted_before_its_photocells_had_the_survey_is_fitted_again_in_place(
    poor_first, tmp_path, replays, kind
):
    """Descent 1 ended before its photocells had a survey covariance (its own fit poor):
    fitted again alone it computes its own, as the replay's fit of it did; descent 2, whose
    reference fit gave the covariance, and a later one take the replay's. (Descent 1's row
    does not show which covariance it took: a poor fit's intervals are its timing-only ones.
    tests/test_survey_handed_on.py compares its fit to the bit; descent 2's row shows it.)"""
    session = tmp_path / "session"
    shutil.copytree(poor_first, session)
    rows = csv_of(session).decode().splitlines()
    assert '"poor-fit"' in rows[-6] and '"ok"' in rows[-5]
    said = RecordedSession(str(session)).annotate(BEFORE_THE_SOURCE[kind])
    assert said.endswith(f"{session / session_folder.RESULTS} rewritten")
    assert replays == []
    assert csv_of(session) == from_scratch(session)


def test_a_model_change_of_an_aborted_descent_is_in_place(tmp_path, replays):
    """Descent 1 a lone start (its other crossings cut from the raw log): no fit, no survey
    covariance for its one photocell; its model changed in place all the same."""
    session = make_session(tmp_path, order="ABBA")
    raw = session / session_folder.RAW
    lines = raw.read_text().splitlines(keepends=True)
    assert json.loads(lines[2])["rx"].startswith(" 0002 C1 ")
    raw.write_text("".join(lines[:2] + lines[10:]))
    RecordedSession(str(session)).annotate([InvalidMark(4, "gate", 1.0)])  # replayed: a state
    assert '"aborted"' in csv_of(session).decode().splitlines()[-4]
    replays.clear()
    RecordedSession(str(session)).annotate([ModelChange(1, FitModel.VELOCITY, 2.0)])
    assert replays == []
    assert csv_of(session) == from_scratch(session)


def damage_missing(session: Path) -> None:
    os.unlink(session / session_folder.RESULTS)


def damage_cut(session: Path) -> None:
    data = csv_of(session)
    (session / session_folder.RESULTS).write_bytes(data[: len(data) - 40])


def damage_hand_edited(session: Path) -> None:
    """One digit of a μ changed: the same size, the same rows."""
    lines = csv_of(session).decode().split("\n")
    cells = lines[-3].split(",")
    mu = cells[8]
    cells[8] = mu[:-1] + ("1" if mu[-1] != "1" else "2")
    lines[-3] = ",".join(cells)
    (session / session_folder.RESULTS).write_text("\n".join(lines), encoding="utf-8")


def damage_row_missing(session: Path) -> None:
    lines = csv_of(session).decode().split("\n")
    del lines[-2]  # the last row (the file ends with a line end)
    (session / session_folder.RESULTS).write_text("\n".join(lines), encoding="utf-8")


def damage_raw_log(session: Path) -> None:
    """A crossing time of the raw log changed (the same size): the results are stale."""
    raw = session / session_folder.RAW
    lines = raw.read_text().splitlines(keepends=True)
    k = next(i for i, line in enumerate(lines) if " C1 " in line and i > 20)  # descent 3 or so
    rec = json.loads(lines[k])
    data = rec["rx"]  # " 0029 C1  10:01:04.6945 00\r": a millisecond more
    ms = data.index(".") + 3
    rec["rx"] = data[:ms] + str((int(data[ms]) + 1) % 10) + data[ms + 1 :]
    lines[k] = json.dumps(rec, separators=(",", ":")) + "\n"
    raw.write_text("".join(lines))


def damage_state(session: Path) -> None:
    (session / STATE).write_text('{"format": 1, "descents": "all"}')


def damage_annotated_by_another(session: Path) -> None:
    """An annotation appended without rewriting the CSV (as a recorder's is)."""
    session_folder.append_annotation(str(session), InvalidMark(4, "seen later", 5.0))


def damage_config(session: Path) -> None:
    cfg = session / session_folder.CONFIG
    cfg.write_text(cfg.read_text().replace("mass_kg: 88", "mass_kg: 84"))


def damage_code(session: Path) -> None:
    state = json.loads((session / STATE).read_text())
    state["code"] = "0" * 64  # written by another station
    (session / STATE).write_text(json.dumps(state))


DAMAGES = [damage_missing, damage_cut, damage_hand_edited, damage_row_missing, damage_raw_log,
           damage_state, damage_annotated_by_another, damage_config, damage_code]  # fmt: skip


@pytest.mark.parametrize("damage", DAMAGES, ids=lambda f: f.__name__[7:])
def test_a_csv_that_is_not_the_states_is_replayed_not_trusted(session, replays, damage):
    if damage is damage_config:
        assert "mass_kg: 88" in (session / session_folder.CONFIG).read_text()
    damage(session)
    RecordedSession(str(session)).annotate([InvalidMark(2, "fell", 9.0)])
    assert replays, "the damaged CSV was trusted"
    assert csv_of(session) == from_scratch(session)
    replays.clear()  # and the replay wrote a state the next annotate can use
    RecordedSession(str(session)).annotate([InvalidMark(6, "gate", 10.0)])
    assert replays == []
    assert csv_of(session) == from_scratch(session)


def test_a_copy_of_the_session_is_annotated_in_place(session, tmp_path, replays):
    """A copy has new file times: the raw log is then read for its hash, which is the same."""
    copy = tmp_path / "copy"
    shutil.copytree(session, copy)
    os.utime(copy / session_folder.RAW, ns=(1, 1))
    RecordedSession(str(copy)).annotate([InvalidMark(2, "fell", 9.0)])
    assert replays == []
    assert csv_of(copy) == from_scratch(copy)


def test_while_recorded_the_csv_and_its_state_are_left_to_the_recorder(session, replays):
    before, state = csv_of(session), (session / STATE).read_bytes()
    lock = session_folder.RecordingLock.take(str(session))
    try:
        said = RecordedSession(str(session)).annotate([InvalidMark(2, "gate", 1.0)])
    finally:
        lock.release()
    assert "being recorded now" in said
    assert csv_of(session) == before and (session / STATE).read_bytes() == state
    assert replays == []


def test_the_descents_are_checked_from_the_state_without_reading_the_csv(session):
    s = RecordedSession(str(session))
    assert s.descent_numbers() == [1, 2, 3, 4, 5, 6]
    s.check_descents([2, 6])
    with pytest.raises(Exception, match="no descent 7"):
        s.check_descents([7])


def test_station_annotate_that_fits_nothing_imports_no_numerics(session):
    """The command as typed: no numpy, scipy, matplotlib or the database for an invalid mark
    (a second of imports that the annotation does not need)."""
    code = (
        "import sys\n"
        "from station.cli.main import main\n"
        f"assert main(['annotate', {str(session)!r}, '--descents', '2', '--invalid', 'x']) == 0\n"
        "print(sorted(m for m in ('numpy', 'scipy', 'matplotlib', 'sqlalchemy', 'pandas')"
        " if m in sys.modules))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("STATION_STORE", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True)  # fmt: skip
    assert out.stdout.strip() == "[]", out.stderr
    assert csv_of(session) == from_scratch(session)


def test_a_state_that_is_a_fifo_or_a_folder_costs_a_replay_not_a_hang(session, replays):
    state = session / STATE
    for make in (os.mkfifo, os.mkdir):
        if state.is_dir():
            os.rmdir(state)
        else:
            os.unlink(state)  # the state the last replay wrote, or the FIFO
        make(state)
        replays.clear()
        RecordedSession(str(session)).annotate([InvalidMark(2, make.__name__, 9.0)])
        assert replays
        assert csv_of(session) == from_scratch(session)


def test_a_failure_in_place_replays_and_says_so(session, replays, monkeypatch):
    from station.session.resultsfile import ResultsFile

    def broken(*args, **kwargs):
        raise RuntimeError("a bug")

    monkeypatch.setattr(ResultsFile, "edit", broken)
    s = RecordedSession(str(session))
    s.annotate([InvalidMark(2, "fell", 9.0)])
    assert replays and any("a bug" in w for w in s.warnings)
    assert csv_of(session) == from_scratch(session)


def test_metadata_on_a_day_whose_config_names_items_by_bib_is_replayed(tmp_path, replays):
    """A bib's item (ski, wax …) overrides what the annotations say; the state does not keep
    the bibs, so such a day's metadata is replayed (its marks are still changed in place)."""
    session = make_session(tmp_path, order="ABBA", config_extra='items:\n  "1": {wax: red}\n')
    RecordedSession(str(session)).annotate([InvalidMark(1, "gate", 1.0)])  # replayed: no state
    replays.clear()
    RecordedSession(str(session)).annotate([InvalidMark(2, "fell", 2.0)])
    assert replays == []
    RecordedSession(str(session)).annotate(
        [MetadataAnnotation(Metadata(wax="green"), descents=(3,), t=3.0)]
    )
    assert replays
    assert csv_of(session) == from_scratch(session)
