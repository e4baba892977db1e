"""Fits are computed once (issue 19): each descent's fit is stored with its session and used
again where everything it depends on is the same; what an annotation changes is fitted again,
and nothing a command writes differs by a byte from a replay with every fit computed."""

from __future__ import annotations

import dataclasses
import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from station.model.fit import FitResult
from station.session import folder as session_folder
from station.session.fitstore import FITS, FitStore, fit_from_json, fit_key, to_json
from station.session.recorded_session import RecordedSession
from station.session.records import InvalidMark, Metadata, MetadataAnnotation, ModelChange
from tests.session_helpers import make_session


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    return make_session(tmp_path_factory.mktemp("day"), order="ABBAAB")


@pytest.fixture
def session(recorded, tmp_path):
    copy = tmp_path / "session"
    shutil.copytree(recorded, copy)
    return copy


def replayed(session) -> tuple[str, FitStore]:
    """The results CSV a replay of the session writes, and its store of fits (hits, misses)."""
    acq = RecordedSession(str(session)).replay()
    out = io.StringIO()
    acq.write_csv_to(out)
    fits = acq.day.analyser.fits
    assert isinstance(fits, FitStore)
    return out.getvalue(), fits


def every_fit_computed(session) -> str:
    """The same, with no stored fit (the file moved away and put back)."""
    path = session / FITS
    kept = path.exists()
    if kept:
        os.rename(path, session / "kept")
    try:
        return replayed(session)[0]
    finally:
        if kept:
            os.rename(session / "kept", path)


def test_a_stored_fit_comes_back_equal_to_the_one_computed(session):
    acq = RecordedSession(str(session)).replay()
    fits = [r.fit for r in acq.results() if r.fit is not None]
    assert fits
    for fit in fits:
        back = fit_from_json(json.loads(json.dumps(to_json(fit))))
        assert back == fit  # every field but the survey covariance (not compared) …
        if fit.survey_time_cov is not None:  # … which comes back to the bit as well
            assert back.survey_time_cov is not None
            assert back.survey_time_cov.tobytes() == fit.survey_time_cov.tobytes()


def test_the_second_replay_computes_no_fit_and_writes_the_same_bytes(session):
    first, fits = replayed(session)
    assert (fits.hits, fits.misses) == (0, 6)
    again, fits = replayed(session)
    assert (fits.hits, fits.misses) == (6, 0)
    assert again == first == (session / session_folder.RESULTS).read_text()


@pytest.mark.parametrize(
    "annotation",
    [
        MetadataAnnotation(Metadata(mass_kg=80.0), descents=(3,), t=1.0),
        MetadataAnnotation(
            Metadata(air_temperature_c=-12.0, pressure_hpa=820.0, humidity_pct=60.0),
            descents=(3,),
            t=1.0,
        ),  # fmt: skip
        ModelChange(3, "velocity", 1.0),  # type: ignore[arg-type]
    ],
    ids=["mass", "air", "model"],
)
def test_an_annotation_that_changes_a_fit_refits_that_descent_only(session, annotation):
    if isinstance(annotation, ModelChange):
        from station.session.records import FitModel

        annotation = ModelChange(3, FitModel.VELOCITY, 1.0)
    replayed(session)  # every fit stored
    RecordedSession(str(session)).annotate([annotation])
    text, fits = replayed(session)
    assert (fits.hits, fits.misses) == (6, 0)  # the annotate stored the new fit of descent 3
    assert text == (session / session_folder.RESULTS).read_text() == every_fit_computed(session)


def test_annotate_refits_one_descent_and_an_invalid_mark_none(session):
    replayed(session)
    s = RecordedSession(str(session))
    s.annotate([InvalidMark(2, "fell", 1.0)])
    fits = s.run().day.analyser.fits
    assert isinstance(fits, FitStore) and (fits.hits, fits.misses) == (6, 0)
    s = RecordedSession(str(session))
    s.annotate([MetadataAnnotation(Metadata(mass_kg=70.0), descents=(5,), t=2.0)])
    fits = s.run().day.analyser.fits
    assert isinstance(fits, FitStore) and (fits.hits, fits.misses) == (5, 1)
    assert (session / session_folder.RESULTS).read_text() == every_fit_computed(session)


def test_the_key_is_everything_the_fit_depends_on():
    parts = {"times_us": [0, 1_000_000], "photocells": ["PC1", "PC2"], "model": "constant",
             "mass_kg": 88.0, "air_density": 1.079, "wind_ms": 0.0, "g": 9.81}  # fmt: skip
    base = fit_key("ctx", parts, None)
    assert fit_key("ctx", dict(parts), None) == base
    for name, value in [("times_us", [0, 1_000_001]), ("mass_kg", 88.5), ("model", "velocity"),
                        ("air_density", 1.08), ("wind_ms", 0.5), ("g", 9.8)]:  # fmt: skip
        assert fit_key("ctx", {**parts, name: value}, None) != base, name
    assert fit_key("other config, survey or code", parts, None) != base
    assert fit_key("ctx", parts, np.eye(2)) != base != fit_key("ctx", parts, 2 * np.eye(2))


def test_a_damaged_store_is_passed_over_and_those_descents_fitted_again(session):
    first, _ = replayed(session)
    lines = (session / FITS).read_text().splitlines()
    rec = json.loads(lines[1])
    rec["fit"]["mu"]["value"] = "a lot"  # the wrong type
    bad_fields = json.loads(lines[2])
    del bad_fields["fit"]["dof"]  # another version's record
    damaged = [lines[0], json.dumps(rec), json.dumps(bad_fields), "{not json", "[1, 2]",
               '{"key": 5, "fit": {}}', *lines[3:], lines[4][:50]]  # fmt: skip
    (session / FITS).write_text("\n".join(damaged))  # the last line torn
    text, fits = replayed(session)
    assert text == first
    assert (fits.hits, fits.misses) == (4, 2)


def test_a_store_that_is_a_fifo_or_unwritable_costs_only_the_fits(session):
    first = every_fit_computed(session)
    os.unlink(session / FITS)  # the replay above stored its fits
    os.mkfifo(session / FITS)
    text, fits = replayed(session)  # a FIFO is not read (it would block): all fitted
    assert text == first and fits.misses == 6
    os.unlink(session / FITS)
    (session / FITS).mkdir()  # cannot be written, whoever runs the test
    text, fits = replayed(session)
    assert text == first and fits.misses == 6


def test_a_store_of_mostly_replaced_fits_is_compacted(session):
    replayed(session)
    stale = [json.dumps({"key": f"{k:064x}", "fit": {}}) for k in range(200)]
    with open(session / FITS, "a") as fh:
        fh.write("\n".join(stale) + "\n")
    replayed(session)
    lines = (session / FITS).read_text().splitlines()
    assert len(lines) == 6
    _text, fits = replayed(session)
    assert fits.hits == 6


def test_the_store_holds_fits_not_code():
    """JSON, never pickle: a session folder from elsewhere cannot run anything."""
    fields = {f.name for f in dataclasses.fields(FitResult)}
    assert {"mu", "cda", "v0", "status"} <= fields
    with pytest.raises(ValueError):
        fit_from_json({"__reduce__": "os.system"})


def test_the_recorder_stores_its_fits_so_the_first_annotate_refits_nothing(recorded, tmp_path):
    """The fits made while recording are the replay's: the first command after a day fits
    nothing again."""
    from station.session.acquisition import Acquisition
    from station.session.rawlog import read_rawlog

    cfg = session_folder.load_session_config(str(recorded))
    new = tmp_path / "recorded-again"
    acq = Acquisition.open(cfg, session_dir=str(new), threaded=False)
    for chunk in read_rawlog(str(recorded / session_folder.RAW)):
        if not chunk.event:
            acq.receive(chunk)
    acq.close()
    assert len((new / FITS).read_text().splitlines()) == 6
    s = RecordedSession(str(new))
    s.annotate([InvalidMark(1, "gate", 1.0)])
    fits = s.run().day.analyser.fits
    assert isinstance(fits, FitStore) and (fits.hits, fits.misses) == (6, 0)


def test_the_store_keeps_where_a_fit_is_not_the_fit(session, tmp_path):
    """In memory a written fit is the offset of its line (a 2000-descent recording kept 6.6 kB
    a descent of JSON forms); asked for again it is read back equal, and a line that is not
    its own any more (the file compacted by another process) is a miss, never a wrong fit."""
    acq = RecordedSession(str(session)).replay()
    fits = [r.fit for r in acq.results() if r.fit is not None]
    path = str(tmp_path / FITS)
    store_ = FitStore(path, "context")
    keys = [f"k{n}" for n in range(len(fits))]
    for key, fit in zip(keys, fits, strict=True):
        store_.put(key, fit)
    assert store_._fits == {} and len(store_._where) == len(fits)
    assert store_.get(keys[-1]) == fits[-1]
    again = FitStore(path, "context")  # opened afresh: offsets from the file
    assert again._fits == {} and again.get(keys[0]) == fits[0]
    lines = Path(path).read_bytes().split(b"\n")
    with open(path, "wb") as fh:  # another process keeps only the last fit, at the start
        fh.write(lines[len(fits) - 1] + b"\n")
    assert store_.get(keys[0]) is None and store_.misses == 1
    assert store_.get(keys[-1]) is None  # its offset now points past the end
