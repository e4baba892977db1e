"""``station survey`` / ``simulate`` / ``fit``: what issue 10 added to their output and options."""

from __future__ import annotations

import json

import pytest
from conftest import DEMO_SURVEY

from station.model.physics import local_gravity

AIR = ["--air-density", "1.04"]


def _with_latitude(tmp_path, latitude: float = 47.0) -> str:
    text = DEMO_SURVEY.read_text().replace(
        "observations: demo_run.gsi", f"observations: {DEMO_SURVEY.parent / 'demo_run.gsi'}"
    )
    path = tmp_path / "lat.yaml"
    path.write_text(text + f"latitude_deg: {latitude}\n")
    return str(path)


def test_survey_reports_scatter_and_local_gravity(run_station, tmp_path):
    r = run_station("survey", _with_latitude(tmp_path), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert 0.003 < out["scatter_m"] < 0.007  # the demo's 5 mm roughness, estimated
    assert out["points_left_out"] == []
    mean_h = sum(pc["y"] for pc in out["photocells"]) / len(out["photocells"])
    assert out["gravity_ms2"] == pytest.approx(local_gravity(47.0, mean_h), abs=2e-5)
    assert "GRS80" in out["gravity_source"]
    r = run_station("survey", DEMO_SURVEY)
    assert "points scatter" in r.stdout and "standard gravity" in r.stdout


def test_gravity_override_and_report(run_station, tmp_path):
    sim = tmp_path / "t.csv"
    survey = _with_latitude(tmp_path)
    args = ["--survey", survey, "--mass", "88", *AIR]
    r = run_station("simulate", *args, "--cda", "0.22", "--mu", "0.0085", "--v0", "3.4",
                    "--csv", sim, "--json")  # fmt: skip
    assert r.returncode == 0, r.stderr
    g_site = json.loads(r.stdout)["gravity_ms2"]
    assert g_site == pytest.approx(9.8031, abs=3e-4)
    r = run_station("fit", *args, "--times", sim, "--json")
    fit = json.loads(r.stdout)
    assert fit["gravity_ms2"] == g_site and fit["mu"] == pytest.approx(0.0085, abs=2e-5)
    # the same times read with standard gravity: μ moves by about g's relative error
    r = run_station("fit", *args, "--times", sim, "--json", "--gravity", "9.80665")
    fit_std = json.loads(r.stdout)
    assert fit_std["gravity_source"] == "given"
    assert fit_std["mu"] - fit["mu"] > 1e-4
    r = run_station("fit", *args, "--times", sim, "--gravity", "98.1")
    assert r.returncode == 2 and "--gravity" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("bad", ["91", "-95", ".nan", "north"])
def test_bad_latitude_is_located(run_station, tmp_path, bad):
    path = tmp_path / "s.yaml"
    path.write_text(_with_latitude(tmp_path) and (tmp_path / "lat.yaml").read_text().replace(
        "latitude_deg: 47.0", f"latitude_deg: {bad}"))  # fmt: skip
    r = run_station("survey", path)
    assert r.returncode == 2
    assert f"{path}:" in r.stderr and "field latitude_deg" in r.stderr


@pytest.mark.parametrize("ext", ["png", "svg"])
def test_survey_plot(run_station, tmp_path, ext):
    out = tmp_path / f"track.{ext}"
    r = run_station("survey", DEMO_SURVEY, "--plot", out)
    assert r.returncode == 0, r.stderr
    data = out.read_bytes()
    assert data.startswith(b"\x89PNG") if ext == "png" else b"<svg" in data[:2000]


def test_plot_shows_left_out_points(tmp_path):
    from station.report.track_plot import plot_track
    from station.simulators.survey_sim import write_demo
    from station.survey.load import load_survey
    from station.survey.track import build_track

    _, y = write_demo(
        str(tmp_path), seed=5, stem="s", spacing=2.5, roughness=0.015, blunders={"P061": 0.25}
    )
    track = build_track(load_survey(y))
    svg = tmp_path / "t.svg"
    plot_track(track, str(svg))
    text = svg.read_text()
    assert "P061" in text and "left out (1)" in text


@pytest.mark.parametrize(
    ("name", "expect"), [("t.jpg", "must be .png or .svg"), ("nowhere/t.png", "folder does not")]
)
def test_bad_plot_path(run_station, tmp_path, name, expect):
    r = run_station("survey", DEMO_SURVEY, "--plot", tmp_path / name)
    assert r.returncode == 2 and expect in r.stderr and "Traceback" not in r.stderr


def test_fit_reports_timing_only_and_total_intervals(run_station, tmp_path):
    sim = tmp_path / "t.csv"
    args = ["--survey", DEMO_SURVEY, "--mass", "88", *AIR]
    r = run_station("simulate", *args, "--cda", "0.22", "--mu", "0.0085", "--v0", "3.4",
                    "--noise-ms", "0.2", "--seed", "3", "--csv", sim)  # fmt: skip
    assert r.returncode == 0, r.stderr
    fit = json.loads(run_station("fit", *args, "--times", sim, "--json").stdout)
    for k in ("mu", "cda", "v0"):
        lo, hi = fit["ci90"][k]
        tlo, thi = fit["ci90_timing"][k]
        assert hi - lo >= thi - tlo and 0 < fit["survey_share"][k] < 1
    assert fit["timer_precision_s"] == 0.5e-3 and fit["status"] == "ok"
    text = run_station("fit", *args, "--times", sim).stdout
    assert "timing only [" in text and "% of the variance" in text and "goodness of fit" in text
    plain = json.loads(run_station("fit", *args, "--times", sim, "--json", "--timing-only").stdout)
    assert plain["ci90_timing"] is None and plain["ci90"]["mu"] == fit["ci90_timing"]["mu"]
    # the same times judged against a 0.02 ms timer and an exact track: far above them
    tight = json.loads(
        run_station("fit", *args, "--times", sim, "--json", "--timer-precision-ms", "0.02",
                    "--timing-only").stdout
    )  # fmt: skip
    assert tight["status"] == "poor-fit" and tight["chi2_p"] < 1e-3


def test_one_degree_of_freedom_claims_no_share_of_the_variance(tmp_path, run_station):
    """Five photocells for four parameters: the timing variance is one squared residual, and
    the fit said the survey explained up to "100 % of the variance"; it now says no share."""
    from tests.conftest import ROOT

    times = tmp_path / "t5.csv"
    lines = (ROOT / "surveys" / "demo_descent.csv").read_text().splitlines()
    times.write_text("\n".join(x for x in lines if not x.startswith(("PC6", "PC7", "PC8", "PC9"))))
    r = run_station("fit", "--survey", ROOT / "surveys" / "demo_run.yaml", "--times", times,
                    "--mass", "88")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "dof 1" in r.stdout and "timing only [" in r.stdout
    assert "of the variance" not in r.stdout
