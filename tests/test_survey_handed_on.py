"""The survey covariance a descent's fit takes does not hang on the order of the fits or on
the annotations (station/session/analysis.py, ``Analyser``): a day fitted as it was recorded
(each descent as it ended, then fitted again as the engineer annotated it) and the same day
replayed (every annotation first) give every descent the same fit, to the last bit.

Linearised at the first good fit *as annotated*, a model or a mass given to descent 1 after
later descents took its covariance gave the recording other intervals than the replay (the
6th significant digit). Real parts: a session's raw log, the day's own analyser."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from station.session import folder as session_folder
from station.session.records import (
    Annotation,
    FitModel,
    Metadata,
    MetadataAnnotation,
    ModelChange,
)
from station.session.runs import replay
from tests.session_helpers import make_session
from tests.test_annotate_in_place import poor_first_descent

ANNOTATIONS: list[Annotation] = [
    ModelChange(1, FitModel.VELOCITY, 2.0),
    MetadataAnnotation(Metadata(mass_kg=70.0), descents=(1, 2, 4), t=3.0),
    MetadataAnnotation(Metadata(pressure_hpa=840.0, air_temperature_c=-9.0), descents=(2,), t=4.0),
]


def as_recorded_and_replayed(session: Path, tmp_path: Path, annotations=ANNOTATIONS):
    """The day fitted as a recording fits it (each descent as it ends, the annotations after
    all of them), and as a replay of the annotated session fits it."""
    cfg = session_folder.load_session_config(str(session))
    live = replay(str(session), cfg, speed_curves=False)  # no annotations yet
    for a in annotations:
        live.day.apply(a)  # fits again the descents it names, after the later ones
    annotated = tmp_path / "annotated"
    shutil.copytree(session, annotated)
    for a in annotations:
        session_folder.append_annotation(str(annotated), a)
    again = replay(
        str(annotated), session_folder.load_session_config(str(annotated)), speed_curves=False
    )
    return live.day, again.day


def assert_same_fits(live, again) -> None:
    assert list(live.results) == list(again.results)
    for n in live.results:
        a, b = live.results[n], again.results[n]
        assert a.row == b.row, n
        fa, fb = a.fit, b.fit
        if fa is None and fb is None:  # an error row: no fit
            continue
        assert fa is not None and fb is not None
        assert np.array_equal(fa.survey_time_cov, fb.survey_time_cov), n
        assert np.array_equal(np.array(fa.covariance), np.array(fb.covariance)), n


@pytest.fixture(scope="module")
def day_dir(tmp_path_factory):
    return make_session(tmp_path_factory.mktemp("day"), order="ABBAAB", annotate=False)


def test_fitted_again_after_later_descents_gives_the_replays_fits(day_dir, tmp_path):
    live, again = as_recorded_and_replayed(day_dir, tmp_path)
    assert_same_fits(live, again)
    # descent 1's reference fit gives the covariance; its own fit (velocity, 70 kg) takes it
    sources = again.analyser.survey_sources()
    assert [n for _, n, _ in sources] == [1]
    assert again.results[1].row.model == FitModel.VELOCITY
    assert np.array_equal(again.results[1].fit.survey_time_cov, sources[0][2])


def test_a_descent_before_the_one_that_gives_the_covariance_keeps_its_own(day_dir, tmp_path):
    """Descent 1 a poor fit: descent 2's reference fit gives the covariance; descent 1
    computes its own, as recorded and as replayed."""
    session = tmp_path / "poor"
    shutil.copytree(day_dir, session)
    poor_first_descent(session)
    live, again = as_recorded_and_replayed(session, tmp_path)
    assert_same_fits(live, again)
    sources = again.analyser.survey_sources()
    assert [n for _, n, _ in sources] == [2]
    own = again.results[1].fit.survey_time_cov
    assert own is not None and not np.array_equal(own, sources[0][2])


def test_a_descent_whose_fit_cannot_run_still_gives_the_covariance(day_dir, tmp_path):
    """A wind without a direction for descent 1 (an error row, no fit): its reference fit
    still gives its photocells the covariance, as it did before the wind was entered, so the
    later descents' fits are the replay's."""
    wind = [MetadataAnnotation(Metadata(wind_ms=2.0), descents=(1,), t=2.0)]
    live, again = as_recorded_and_replayed(day_dir, tmp_path, wind)
    assert again.results[1].row.status == "error"
    assert_same_fits(live, again)
    assert [n for _, n, _ in again.analyser.survey_sources()] == [1]
