"""The timer's precision in one place: the config key, the resolution the timer states, one
option on every command, and the single fits and the day judged against the same timer."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from station.model.timer import PHOTOCELL_JITTER_S, TIMER_PRECISION_S, precision_from_resolution
from tests.session_helpers import make_session
from tests.timing_helpers import write_config


def test_a_coarse_timer_is_as_precise_as_its_rounding_allows():
    """A timer rounding to 1/100 s: the SD of its rounding error, measured on simulated times,
    and the photocell's jitter on top; a fine timer is credited with no less than 0.5 ms."""
    rng = np.random.default_rng(7)
    t = rng.uniform(0.0, 100.0, 200_000)
    rounding_sd = float(np.std(t - np.round(t, 2)))
    coarse = precision_from_resolution(10_000)
    assert rounding_sd < coarse < rounding_sd + PHOTOCELL_JITTER_S
    assert coarse == pytest.approx(math.hypot(rounding_sd, PHOTOCELL_JITTER_S), rel=0.01)
    for fine in (None, 0, 10, 100, 1000):  # not stated, TAG, ALGE, Microgate
        assert precision_from_resolution(fine) == TIMER_PRECISION_S


def test_the_config_states_the_timer_precision(tmp_path, run_station):
    from station.session.config import load_config

    assert load_config(str(write_config(tmp_path, "loop://"))).timer_precision_s is None
    cfg = write_config(tmp_path, "loop://", extra="timer: {precision_ms: '1,5'}\n")
    assert load_config(str(cfg)).timer_precision_s == pytest.approx(1.5e-3)
    cfg.write_text(cfg.read_text().replace("'1,5'", "500"))
    r = run_station("replay", cfg, "--config", cfg)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert ":6: field timer.precision_ms: must lie between 0.01 and 100 ms" in r.stderr


def test_the_processor_takes_the_resolution_of_a_photocell_not_a_keypad(tmp_path, demo_track):
    """ALGE sends a keypad start to 1/100 s and photocells to 1/10 000 s: a manual start first
    must not make every descent of the day coarse."""
    from station.session.config import load_config
    from station.session.day import Day
    from station.session.rawlog import Chunk
    from station.timing.wireformats import format_alge

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    day = Day.start(cfg, demo_track)
    assert day.timer_precision_s() == TIMER_PRECISION_S  # nothing stated yet
    day.processor.feed(Chunk(1.0, (format_alge("C0M", 36_000_120_000) + "\r").encode()))
    assert day.processor.resolution_us is None
    day.processor.feed(Chunk(2.0, (format_alge("C0", 36_001_000_000, 1) + "\r").encode()))
    assert day.processor.resolution_us == 100
    day.processor.resolution_us = 10_000  # a timer that gives photocells to 1/100 s
    assert day.timer_precision_s() == precision_from_resolution(10_000)
    cfg.timer_precision_s = 2e-3  # the config's word comes first
    assert day.timer_precision_s() == 2e-3


def test_the_descents_and_the_day_are_judged_against_the_configs_timer(tmp_path, run_station):
    session = make_session(tmp_path, order="ABAB", config_extra="timer: {precision_ms: 3}\n")
    from station.session.recorded_session import RecordedSession

    results = RecordedSession(str(session)).results()
    assert {r.fit.timer_precision_s for r in results if r.fit} == {3e-3}
    r = run_station("compare", session, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["timer_sd_s"] == 3e-3
    r = run_station("compare", session, "--json", "--timer-ms", "0.5")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["timer_sd_s"] == 5e-4


def test_one_option_name_and_the_old_one_still_works(run_station):
    fit = ["fit", "--survey", "surveys/demo_run.yaml", "--times", "surveys/demo_descent.csv",
           "--mass", "88", "--air-density", "1.079"]  # fmt: skip
    new = run_station(*fit, "--timer-ms", "0.3", "--json")
    old = run_station(*fit, "--timer-precision-ms", "0.3", "--json")
    assert new.returncode == old.returncode == 0, new.stderr + old.stderr
    assert json.loads(new.stdout)["timer_precision_s"] == 3e-4 and new.stdout == old.stdout
    helped = run_station("fit", "--help").stdout
    assert "--timer-ms" in helped and "--timer-precision-ms" not in helped
    assert "--timer-ms" in run_station("compare", "--help").stdout
