"""The ``station`` command as a user runs it: real files, exit codes, what it prints. The
commands run in this process (``run_station``); the installed command runs as a process once."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from tests.conftest import DEMO_SURVEY

AIR = ["--pressure-hpa", "835", "--temperature-c", "-4", "--humidity-pct", "70"]


def test_survey_json(run_station):
    r = run_station("survey", DEMO_SURVEY, "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert {"length_m", "drop_m", "residual_rms_m", "photocells", "profile"} <= set(d)
    assert [p["id"] for p in d["photocells"]] == [f"PC{i}" for i in range(1, 10)]
    assert set(d["photocells"][0]) >= {"id", "x", "y", "slope_deg"}
    assert set(d["profile"]) == {"x", "y", "slope_deg", "curvature"}
    assert 330 < d["length_m"] < 350


def test_survey_text_and_csv(run_station, tmp_path):
    out = tmp_path / "profile.csv"
    r = run_station("survey", DEMO_SURVEY, "--csv", out)
    assert r.returncode == 0 and "PC9" in r.stdout and "residual RMS" in r.stdout
    df = pd.read_csv(out)
    assert list(df.columns) == ["x_m", "y_m", "slope_deg", "curvature_1_per_m"]
    assert len(df) > 300


def test_simulate_then_fit_recovers_the_truth(run_station, tmp_path):
    times = tmp_path / "times.csv"
    r = run_station(
        "simulate", "--survey", DEMO_SURVEY, "--mass", "88", "--cda", "0.22", "--mu", "0.0085",
        "--v0", "3.4", *AIR, "--noise-ms", "0.5", "--seed", "4", "--start-s", "38045.1234",
        "--csv", times, "--json",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    sim = json.loads(r.stdout)
    assert {"photocells", "min_normal_force_n", "air_density"} <= set(sim)
    assert set(sim["photocells"][0]) == {"id", "x", "t", "v"}
    r = run_station(
        "fit", "--survey", DEMO_SURVEY, "--times", times, "--mass", "88", *AIR, "--json"
    )
    assert r.returncode == 0, r.stderr
    fit = json.loads(r.stdout)
    assert fit["status"] == "ok"
    for k, v in (("mu", 0.0085), ("cda", 0.22), ("v0", 3.4)):
        lo, hi = fit["ci90"][k]
        assert lo <= v <= hi
    assert fit["dof"] == 5 and len(fit["residuals_s"]) == 9
    assert fit["air_density"] == pytest.approx(sim["air_density"])


def test_fit_accepts_time_of_day(run_station, tmp_path):
    times = tmp_path / "tod.csv"
    r = run_station(
        "simulate", "--survey", DEMO_SURVEY, "--mass", "88", "--cda", "0.22", "--mu", "0.0085",
        "--v0", "3.4", *AIR, "--csv", times,
    )  # fmt: skip
    assert r.returncode == 0
    df = pd.read_csv(times)
    # 23:59:55 start: the descent crosses midnight
    tod = [f"{int((86395 + t) // 3600) % 24:02d}:{int((86395 + t) % 3600 // 60):02d}:"
           f"{(86395 + t) % 60:07.4f}" for t in df["time"]]  # fmt: skip
    pd.DataFrame({"photocell": df["photocell"], "time": tod}).to_csv(times, index=False)
    r = run_station("fit", "--survey", DEMO_SURVEY, "--times", times, "--mass", "88", *AIR)
    assert r.returncode == 0, r.stderr
    assert "status  ok" in r.stdout
    # times written at 0.1 ms: the rounding alone moves μ by ~1e-5
    mu = float(r.stdout.split("μ ", 1)[1].split()[0])
    assert mu == pytest.approx(0.0085, abs=2e-5)


def test_fit_traverse(run_station, tmp_path):
    import numpy as np

    from station.model.traverse import simulate_traverse

    t = np.linspace(0, 6, 120)
    s, _, _ = simulate_traverse(t, 0.5, 0.1, 1.0, 25, 30, 88, 1.0)
    data = tmp_path / "trav.csv"
    pd.DataFrame({"t": t, "s": s}).to_csv(data, index=False)
    r = run_station(
        "fit-traverse", "--data", data, "--slope-deg", "25", "--traverse-deg", "30",
        "--mass", "88", "--air-density", "1.0", "--json",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["status"] == "ok" and d["mu"] == pytest.approx(0.1, abs=1e-6)
    assert set(d["ci90"]) == {"cda", "mu", "v0", "s0"}


def _times(tmp_path, rows, name="t.csv"):
    p = tmp_path / name
    p.write_text("photocell,time\n" + "".join(f"{a},{b}\n" for a, b in rows))
    return p


GOOD = [(f"PC{i}", f"{t:.4f}") for i, t in enumerate([0, 4.5, 6.9, 8.9, 10.7, 12.3], start=1)]


def _bad_survey(tmp_path, gsi_line: str):
    gsi = (DEMO_SURVEY.parent / "demo_run.gsi").read_text().splitlines()
    gsi[3] = gsi_line
    (tmp_path / "demo_run.gsi").write_text("\r\n".join(gsi) + "\r\n")
    yml = tmp_path / "s.yaml"
    yml.write_text(DEMO_SURVEY.read_text())
    return yml


@pytest.mark.parametrize(
    ("case", "expect"),
    [
        ("malformed_word", "demo_run.gsi:4: field WI 22 (zenith angle): word"),
        ("unknown_unit", "demo_run.gsi:4: field WI 21 (Hz): word"),
        ("unobserved_photocell", "s.yaml:22: field photocells PC9: photocell point 'PCXL'"),
        ("unknown_key", "s.yaml:1: field nmae: unknown key"),
        ("unknown_photocell", "t.csv:3: field photocell: unknown photocell 'PC42'"),
        ("non_increasing", "t.csv:4: field time: time at PC3 is not later than at PC2"),
        ("too_few_rows", "t.csv:2: 1 time(s); a descent needs at least two photocells"),
        ("bad_time", "t.csv:3: field time: 'four' is not a number"),
        ("negative_mass", "argument --mass: '-80' kg is out of range (20 .. 200)"),
        ("unknown_option", "unrecognized arguments: --masss"),
        ("missing_file", "cannot read times file"),
        ("bad_humidity", "argument --humidity-pct: must lie between 0 and 100"),
    ],
)
def test_bad_input_gets_one_line_and_exit_2(run_station, tmp_path, case, expect):
    survey = DEMO_SURVEY
    rows = list(GOOD)
    extra: list[str] = []
    if case == "malformed_word":
        survey = _bad_survey(tmp_path, "*110004+000000000000P003 21.322+0000000036277312 "
                             "22.322+00000000083O3350 31..06+0000000000647968")  # fmt: skip
    elif case == "unknown_unit":
        survey = _bad_survey(tmp_path, "*110004+000000000000P003 21.329+0000000036277312")
    elif case == "unobserved_photocell":
        survey = tmp_path / "s.yaml"
        (tmp_path / "demo_run.gsi").write_text((DEMO_SURVEY.parent / "demo_run.gsi").read_text())
        survey.write_text(DEMO_SURVEY.read_text().replace("[PC9L, PC9R]", "[PCXL, PC9R]"))
    elif case == "unknown_key":
        survey = tmp_path / "s.yaml"
        (tmp_path / "demo_run.gsi").write_text((DEMO_SURVEY.parent / "demo_run.gsi").read_text())
        text = DEMO_SURVEY.read_text().splitlines()
        survey.write_text("nmae: x\n" + "\n".join(text) + "\n")
    elif case == "unknown_photocell":
        rows[1] = ("PC42", "4.5")
    elif case == "non_increasing":
        rows[2] = ("PC3", "4.4")
    elif case == "too_few_rows":
        rows = rows[:1]
    elif case == "bad_time":
        rows[1] = ("PC2", "four")
    elif case == "negative_mass":
        extra = ["--mass", "-80"]
    elif case == "unknown_option":
        extra = ["--masss", "80"]
    elif case == "bad_humidity":
        extra = ["--humidity-pct", "120"]
    times = _times(tmp_path, rows)
    if case == "missing_file":
        times = tmp_path / "nope.csv"
    args = ["fit", "--survey", survey, "--times", times]
    if case not in ("negative_mass",):
        args += ["--mass", "88"]
    r = run_station(*args, *extra, "--air-density", "1.0") if case != "bad_humidity" else (
        run_station(*args, *extra, "--pressure-hpa", "850"))  # fmt: skip
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert expect in lines[0], lines[0]


def test_a_bare_gsi_file_lists_its_reduced_points(run_station, real, tmp_path):
    out = tmp_path / "points.csv"
    r = run_station("survey", real / "leica_gsi" / "leica_gsi16_gurob.gsi", "--csv", out)
    assert r.returncode == 0, r.stderr
    assert "GDEM5415" in r.stdout and "has no photocells" in r.stderr
    df = pd.read_csv(out)
    row = df[df["point"] == "GDEM5415"].iloc[0]
    assert (row["e"], row["n"]) == pytest.approx((8.0757, 11.2167), abs=1e-4)
    r = run_station("survey", real / "leica_gsi" / "RILIEVO.gsi", "--json")
    assert len(json.loads(r.stdout)["points"]) == 23


def test_velocity_model_always_reports_mu1_with_its_interval(run_station):
    times = DEMO_SURVEY.parent / "demo_descent.csv"
    r = run_station(
        "fit", "--survey", DEMO_SURVEY, "--times", times, "--mass", "88", *AIR,
        "--model", "velocity", "--json",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert "mu1" in d and "mu1" in d["ci90"]
    # nine photocells at 0.5 ms cannot separate μ1 from 0: it is shown with its interval
    # (hiding it would select the values shown for being large) and flagged
    lo, hi = d["ci90"]["mu1"]
    assert d["mu1"] is not None and lo <= d["mu1"] <= hi
    assert "mu1" not in d["not_identifiable"]
    assert ("mu1" in d["consistent_with_zero"]) == (lo <= 0.0)


def test_the_installed_command_runs_as_a_process(run_station_process, tmp_path):
    """The console script, its exit status and its streams, in a real process: the README's
    worked example, and bad input as one line on stderr with exit status 2."""
    times = DEMO_SURVEY.parent / "demo_descent.csv"
    r = run_station_process("fit", "--survey", DEMO_SURVEY, "--times", times, "--mass", "88", *AIR)
    assert r.returncode == 0, r.stderr
    assert "status  ok" in r.stdout and "μ       0.00840" in r.stdout
    r = run_station_process("fit", "--survey", DEMO_SURVEY, "--times", tmp_path / "nope.csv",
                            "--mass", "88")  # fmt: skip
    assert r.returncode == 2 and r.stdout == ""
    assert len(r.stderr.strip().splitlines()) == 1 and "cannot read times file" in r.stderr


def test_a_mistyped_command_gets_a_did_you_mean(run_station):
    r = run_station("raport", "s")
    assert r.returncode == 2
    assert (
        r.stderr == "station: error: unknown command 'raport' (did you mean report?) (see --help)\n"
    )
    r = run_station("xyzzy")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert r.stderr.startswith("station: error: unknown command 'xyzzy'; the commands: survey, ")


def test_one_item_is_one_item(tmp_path, run_station):
    """The comparison's first line said '1 items' for a day of one test item."""
    from tests.session_helpers import make_session

    session = make_session(tmp_path, order="AA")
    r = run_station("compare", session)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("joint fit of 2 descents, 1 item, "), r.stdout


def test_demo_and_live_refuse_an_existing_session_in_one_line(tmp_path, run_station):
    """It was a ~120-line Textual traceback, exit 1, from inside the UI."""
    from tests.session_helpers import make_session
    from tests.timing_helpers import write_config

    session = make_session(tmp_path, order="A", annotate=False)
    cfg = write_config(tmp_path, "loop://")
    for args in (["demo"], ["live", "--config", cfg]):
        r = run_station(*args, "--session-dir", session)
        assert r.returncode == 2, r.stderr
        assert r.stderr == (
            f"station: error: {session}: a session is already recorded there; "
            "choose a new --session-dir\n"
        )


def test_the_demo_session_records_the_port_it_opened(tmp_path):
    """The demo's raw log began with port /tmp/station-timer (the bundled config's) while the
    demo read a pty of its own behind a temporary link: the first record names the link now,
    as the 'connected' record after it does, and the current reader reads it."""
    from station.cli.terminal import demo_config
    from station.session.acquisition import Acquisition
    from station.session.folder import load_session_config
    from station.session.rawlog import read_rawlog

    link = str(tmp_path / "station-demo-x" / "timer")
    cfg = demo_config(link)
    assert cfg.serial.port == link and f"port: {link}" in cfg.text
    acq = Acquisition.open(cfg, session_dir=str(tmp_path / "s"))
    acq.close()
    first = next(iter(read_rawlog(str(tmp_path / "s" / "raw.jsonl"))))
    assert first.event == "session" and link in str(first.detail), first
    assert load_session_config(str(tmp_path / "s")).serial.port == link  # the session's copy
