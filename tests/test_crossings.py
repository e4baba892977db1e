"""Crossing times out: ``station replay … --times`` and ``station export SESSION --times``."""

from __future__ import annotations

import numpy as np
import pandas as pd

from station.model.physics import Conditions, Params, StraightRun
from station.timing.wireformats import format_alge
from tests.timing_helpers import write_config


def test_replay_times_of_the_real_race_equal_the_timers_run_times(tmp_path, real, run_station):
    """End to end: the crossing times CSV of a real race capture, finish t_s per bib truncated
    to 0.01 s, equals the last run time (RT line) the timer printed for that bib."""
    cfg = write_config(tmp_path, "/dev/null", channels={"C0": "PC1", "C1": "PC9"},
                       extra="descent: {pairing: bib}\n")  # fmt: skip
    cap = real / "alge" / "ALGETdC8001-202002021133.dump"
    out = tmp_path / "times.csv"
    r = run_station("replay", cap, "--config", cfg, "--times", out, "--date", "2020-02-02")
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(out, dtype={"bib": str, "channel": str})
    assert list(df.columns) == ["descent", "bib", "photocell", "channel", "time_of_day", "t_s",
                                "residual_ms"]  # fmt: skip
    assert df["time_of_day"].str.fullmatch(r"\d\d:\d\d:\d\d\.\d{4}").all()
    finish = df[df["photocell"] == "PC9"].groupby("bib")["t_s"].last()
    rt = {}
    for s in cap.read_text().splitlines():
        if s[6:8] == "RT" and s[0] in " i":
            h, m, sec = s[10:23].strip().split(":")
            rt[s[1:5].lstrip("0")] = round((int(h) * 3600 + int(m) * 60 + float(sec)) * 100)
    assert len(rt) > 50
    for bib, cs in rt.items():
        assert int(round(finish[bib] * 1e4)) // 100 == cs, bib


def test_times_carry_the_fit_residuals(tmp_path, demo_track, run_station):
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    t = run.solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079)).t
    rng = np.random.default_rng(2)
    t = t + np.concatenate([[0], rng.normal(0, 3e-4, len(t) - 1)])
    lines = [format_alge(f"C{i}", int((36_000 + ti) * 1e6), i + 1) + "\r" for i, ti in enumerate(t)]
    cap = tmp_path / "cap.txt"
    cap.write_text("".join(lines), newline="")
    cfg = write_config(tmp_path, "/dev/null")
    out = tmp_path / "times.csv"
    r = run_station("replay", cap, "--config", cfg, "--times", out)
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(out)
    assert len(df) == 9 and (df["descent"] == 1).all()
    assert np.allclose(df["t_s"], np.floor((t - t[0]) * 1e4 + 1e-6) / 1e4, atol=1.01e-4)
    assert np.isnan(df["residual_ms"].iloc[0])
    res = df["residual_ms"].iloc[1:]
    assert res.notna().all() and (res.abs() < 2.0).all() and res.abs().max() > 0.01
    assert df["time_of_day"].iloc[0] == "10:00:00.0000"


def test_export_needs_an_output(tmp_path, run_station):
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "raw.jsonl").write_text("")
    r = run_station("export", tmp_path / "s")
    assert r.returncode == 2 and "--times" in r.stderr


def test_the_bib_names_the_item_in_the_results(tmp_path, demo_track, run_station):
    """items: {12: {ski: A, wax: blue}}: the skier's bib says which ski was tested."""
    from station.timing.wireformats import format_tag

    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    t = run.solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079)).t
    lines = []
    for k, bib in enumerate(["12", "7"]):
        for i, ti in enumerate(t):
            tod = int((36_000 + 60 * k + ti) * 1e6)
            lines.append(format_tag(str(i + 1), tod, 9 * k + i + 1, bib, 9500) + "\r\n")
    cap = tmp_path / "cap.txt"
    cap.write_text("".join(lines), newline="")
    channels = {str(i + 1): f"PC{i + 1}" for i in range(9)}
    cfg = write_config(tmp_path, "/dev/null", "tag", channels,
                       extra="ski: default\nitems: {12: {ski: A, wax: blue}}\n")  # fmt: skip
    out = tmp_path / "r.csv"
    r = run_station("replay", cap, "--config", cfg, "--csv", out)
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(out, comment="#")
    assert list(df["ski"]) == ["A", "default"] and df.loc[0, "wax"] == "blue"
    assert list(df["status"]) == ["ok", "ok"]


def test_a_disconnect_is_on_the_open_descents_flags(tmp_path, demo_track):
    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "/dev/null")))
    proc = Processor(cfg, demo_track)
    proc.feed(Chunk(1.0, (format_alge("C0", 36_000_000_000, 1) + "\r").encode()))
    proc.feed(Chunk(2.0, b"", "disconnected", "read failed"))
    done = proc.finish()
    assert any("timer disconnected (read failed)" in f for f in done[0].flags)
