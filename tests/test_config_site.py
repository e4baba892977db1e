"""The station config's ``latitude_deg`` / ``altitude_m``: validated like every number, used for
local gravity when the survey has none, and the survey's (measured on the run) preferred, with
one warning line, when the two disagree."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from station.model.physics import G_STANDARD, Conditions, Params, StraightRun, local_gravity
from station.session.config import load_config, site_track
from tests.session_helpers import make_session
from tests.timing_helpers import write_config


def _config(tmp_path, extra: str):
    return load_config(str(write_config(tmp_path, "loop://", extra=extra)))


def test_latitude_and_altitude_are_read_with_a_decimal_comma(tmp_path):
    cfg = _config(tmp_path, "latitude_deg: 46,95\naltitude_m: '1650,5'\n")
    assert cfg.latitude_deg == pytest.approx(46.95) and cfg.altitude_m == pytest.approx(1650.5)
    plain = _config(tmp_path, "")
    assert plain.latitude_deg is None and plain.altitude_m is None


@pytest.mark.parametrize(
    ("extra", "expect"),
    [
        ("latitude_deg: 95\n", ":6: field latitude_deg: must lie between -90 and 90 °, got 95"),
        ("latitude_deg: .nan\n", ":6: field latitude_deg:"),
        ("latitude_deg: -.inf\n", ":6: field latitude_deg:"),
        ("latitude_deg: 46.9N\n", ":6: field latitude_deg:"),
        ("latitude_deg: '4,6.9'\n", ":6: field latitude_deg:"),
        ("latitude_deg: true\n", ":6: field latitude_deg:"),
        ("latitude_deg: 47\naltitude_m: 16500\n", ":7: field altitude_m: must lie between -500"),
        ("altitude_m: [1650]\n", ":6: field altitude_m:"),
        ("latitude_deg: 47\nlatitude: 47\n", ":7: field latitude: unknown key"),
    ],
)
def test_a_bad_site_is_one_line_naming_file_line_and_field(tmp_path, run_station, extra, expect):
    cfg = write_config(tmp_path, "loop://", extra=extra)
    r = run_station("replay", cfg, "--config", cfg)  # any command that loads the config
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert str(cfg) in lines[0] and expect in lines[0], lines[0]


def test_the_configs_latitude_gives_the_days_gravity_when_the_survey_has_none(
    tmp_path, demo_track, demo_xs
):
    """Times made with the gravity of 47° N, 1650 m give back μ with the config's site, and a
    biased μ with standard gravity (the survey alone)."""
    assert demo_track.latitude_deg is None  # the demo survey gives no latitude
    from station.session.analysis import Analyser, FitJob
    from station.session.records import DescentStatus, DescentTimes, FitModel, Metadata

    cfg = _config(tmp_path, "latitude_deg: 47\naltitude_m: 1650\n")
    g = local_gravity(47.0, 1650.0)
    truth = Params(0.22, 0.0085, 3.4)
    t = StraightRun(demo_track.profile, demo_xs).solve(truth, Conditions(88.0, 1.04, g=g)).t
    descent = DescentTimes(
        1, tuple(demo_track.photocell_ids), tuple(int(round(x * 1e6)) for x in t),
        DescentStatus.COMPLETE,
    )  # fmt: skip
    job = FitJob(descent, "2026-02-12T10:00:00+00:00", Metadata(), FitModel.CONSTANT, 88.0, 1.04)
    analyser = Analyser(cfg, demo_track)
    assert analyser.site_warning == ""
    assert analyser.gravity.value == pytest.approx(g, abs=1e-9)
    res = analyser.run(job)
    assert res.row.gravity == pytest.approx(g, abs=1e-9)
    assert res.fit.mu.value == pytest.approx(0.0085, abs=2e-6)
    plain = Analyser(_config(tmp_path, ""), demo_track)
    assert plain.gravity.value == G_STANDARD
    assert abs(plain.run(job).fit.mu.value - 0.0085) > 5e-5


def test_the_surveys_latitude_wins_and_a_disagreement_is_one_warning(tmp_path, demo_track):
    surveyed = dataclasses.replace(demo_track, latitude_deg=47.0, altitude_m=None)
    near = _config(tmp_path, "latitude_deg: 47.08\naltitude_m: 1650\n")
    site, warning = site_track(surveyed, near)
    assert warning == "" and site.latitude_deg == 47.0 and site.altitude_m == 1650.0
    far = _config(tmp_path, "latitude_deg: -47.0\n")  # a sign slip: southern hemisphere
    site, warning = site_track(surveyed, far)
    assert site.latitude_deg == 47.0 and site.altitude_m is None
    assert "the survey's 47.000°" in warning and "-47.000°" in warning
    assert "station.yaml" in warning and "demo_run.yaml" in warning and "\n" not in warning
    # altitude: the survey's too, when it gives one
    both = dataclasses.replace(demo_track, latitude_deg=None, altitude_m=1700.0)
    site, _ = site_track(both, near)
    assert (site.latitude_deg, site.altitude_m) == (47.08, 1700.0)
    assert site_track(demo_track, None) == (demo_track, "")


def test_a_session_replays_with_its_configs_site_and_says_which_latitude(tmp_path, run_station):
    session = make_session(tmp_path, order="AB")
    before = pd.read_csv(session / "results.csv", comment="#")
    assert np.allclose(before["gravity"], G_STANDARD)
    cfg = session / "config.yaml"
    cfg.write_text(cfg.read_text() + "latitude_deg: 47\naltitude_m: 1650\n")
    out = tmp_path / "export.csv"
    r = run_station("export", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    after = pd.read_csv(out, comment="#")
    assert np.allclose(after["gravity"], local_gravity(47.0, 1650.0), rtol=0, atol=1e-5)
    assert not np.allclose(after["mu"], before["mu"], rtol=0, atol=1e-6)
    r = run_station("replay", session)
    assert "warning" not in r.stdout + r.stderr
    # the session's survey gives another latitude: the survey's is used, and said once
    survey = session / "survey" / "demo_run.yaml"
    survey.write_text(survey.read_text() + "latitude_deg: 46.5\n")
    r = run_station("replay", session)
    assert r.returncode == 0, r.stderr
    said = [ln for ln in (r.stdout + r.stderr).splitlines() if "latitude_deg" in ln]
    assert len(said) == 1 and "the survey's 46.500°" in said[0], r.stdout + r.stderr
    r = run_station("export", session, "--csv", out)
    after = pd.read_csv(out, comment="#")
    assert np.allclose(after["gravity"], local_gravity(46.5, 1650.0), rtol=0, atol=1e-5)
