"""Test-day analysis: the joint fit, comparisons, drift, wind, and the proof of the issue."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from reference_dae import simulate_dae

from station.model.compare import DescentData, joint_fit
from station.model.fit import fit_descent
from station.model.physics import Conditions, Params, StraightRun
from station.session.day import along_track_wind
from tests.timing_helpers import record_with_sim

RHO = 1.079


def synthetic(demo_track, order: str, mus: dict[str, float], drift_per_hour=0.0, seed=0,
              noise_s=5e-4, step_h=0.05) -> list[DescentData]:  # fmt: skip
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    rng = np.random.default_rng(seed)
    out = []
    for k, item in enumerate(order):
        mu = mus[item] + drift_per_hour * k * step_h
        t = run.solve(
            Params(0.22, mu, rng.uniform(2.5, 4.5)), Conditions(88, RHO), sensitivities=False
        ).t
        t = np.round(t + np.concatenate([[0.0], rng.normal(0, noise_s, len(t) - 1)]), 4)
        out.append(DescentData(k + 1, item, "skier", tuple(demo_track.photocell_ids), t - t[0],
                               10 + k * step_h, 88.0, RHO, 0.0, (0.25, 0.02, 3.0)))  # fmt: skip
    return out


def test_two_items_are_told_apart_and_drift_is_corrected(demo_track):
    data = synthetic(demo_track, "ABBAABBA", {"A": 0.0085, "B": 0.0095}, drift_per_hour=0.02)
    res = joint_fit(demo_track, data)
    assert res.ranking == ["A", "B"]
    c = res.comparisons[0]
    assert (c.a, c.b) == ("A", "B")
    assert c.ci90[1] < 0 and c.ci90[0] <= -0.001 <= c.ci90[1] and c.p_a_faster > 0.99
    d, (lo, hi) = res.drift_per_hour
    assert lo <= 0.02 <= hi and res.drift_separable
    assert res.cda["skier"][0] == pytest.approx(0.22, abs=0.002)


def test_without_drift_correction_the_drift_biases_the_comparison(demo_track):
    data = synthetic(demo_track, "AABB", {"A": 0.009, "B": 0.009}, drift_per_hour=0.02, step_h=0.1)
    biased = joint_fit(demo_track, data, drift="off").comparisons[0]
    assert biased.ci90[1] < 0  # B came later on slower snow: "A is faster", wrongly
    res = joint_fit(demo_track, data, drift="on")
    assert not res.drift_separable
    assert any("cannot separate drift from item" in w for w in res.warnings)


def test_intervals_of_delta_mu_are_calibrated(demo_track):
    """Equal items: the 90 % intervals of Δμ and of the drift hold nine times in ten."""
    n = 60
    hits = drift_hits = 0
    for seed in range(n):
        data = synthetic(demo_track, "ABBAABBA", {"A": 0.009, "B": 0.009}, 0.02, seed=seed)
        res = joint_fit(demo_track, data)
        lo, hi = res.comparisons[0].ci90
        hits += lo <= 0 <= hi
        dlo, dhi = res.drift_per_hour[1]
        drift_hits += dlo <= 0.02 <= dhi
    assert 0.8 <= hits / n <= 0.98, hits
    assert 0.8 <= drift_hits / n <= 0.98, drift_hits


def test_no_drift_without_a_recurring_reference(demo_track):
    data = synthetic(demo_track, "AB", {"A": 0.0085, "B": 0.0095})
    res = joint_fit(demo_track, data)
    assert res.drift_per_hour is None
    assert any("does not recur" in w for w in res.warnings)


def test_delta_mu_in_time_over_the_run_agrees_with_the_dae(demo_track):
    data = synthetic(demo_track, "ABBA", {"A": 0.0085, "B": 0.0095}, noise_s=1e-5)
    res = joint_fit(demo_track, data, drift="off")
    c = res.comparisons[0]
    xs = np.array([pc.x for pc in demo_track.photocells])
    a, b = (next(i.mu for i in res.items if i.item == k) for k in ("A", "B"))
    cda = res.cda["skier"][0]
    ta = simulate_dae(demo_track.profile, xs, Params(cda, a, res.typical_v0), Conditions(88, RHO)).t
    tb = simulate_dae(demo_track.profile, xs, Params(cda, b, res.typical_v0), Conditions(88, RHO)).t
    assert c.delta_t_s == pytest.approx(ta[-1] - tb[-1], abs=1e-6)
    assert -0.05 < c.delta_t_s < -0.01  # 0.001 in μ is some 30 ms over 344 m


def test_along_track_wind_and_its_effect_on_the_fit(demo_track):
    az = demo_track.azimuth_deg
    assert along_track_wind(3.0, az + 180.0, az) == pytest.approx(3.0)  # from uphill: tailwind
    assert along_track_wind(3.0, az, az) == pytest.approx(-3.0)  # from downhill: headwind
    assert along_track_wind(3.0, az + 90.0, az) == pytest.approx(0.0, abs=1e-12)
    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, RHO, 2.0))
        .t
    )
    right = fit_descent(demo_track.profile, xs, t, Conditions(88, RHO, 2.0))
    wrong = fit_descent(demo_track.profile, xs, t, Conditions(88, RHO, 0.0))
    assert right.estimates["mu"] == pytest.approx(0.0085, abs=1e-6)
    assert abs(wrong.estimates["mu"] - 0.0085) > 5e-4 or abs(wrong.estimates["cda"] - 0.22) > 0.02


def _record_day(tmp_path, skis: str, seed: int):
    """Eight descents in ABBAABBA on a drifting track, recorded from the simulated timer."""
    _, session, _ = record_with_sim(
        tmp_path,
        ["--speed", "20", "--first-after", "4", "--hold", "1", "--descents", "8",
         "--interval", "60", "--skis", skis, "--order", "ABBAABBA", "--noise-ms", "0.5",
         "--mu-drift-per-hour", "0.02", "--seed", str(seed)],
        max_descents=8,
    )  # fmt: skip
    return session


@pytest.mark.slow  # a simulated timer on a pty, in real time
@pytest.mark.parametrize(
    ("skis", "differ", "seed"), [("0.0085,0.0095", True, 3), ("0.0090,0.0090", False, 4)]
)
def test_proof_with_the_simulated_timer(tmp_path, run_station, skis, differ, seed):
    """The issue's proof. A 90 % interval misses one time in ten by design (the next test
    measures that), so each case has a fixed seed; the simulation is seeded end to end."""
    session = _record_day(tmp_path, skis, seed=seed)
    for descents, ski in (("1,4,5,8", "pair A"), ("2,3,6,7", "pair B")):
        r = run_station("annotate", session, "--descents", descents, "--ski", ski, "--wax", "blue")
        assert r.returncode == 0, r.stderr
    out = tmp_path / "cmp.csv"
    r = run_station("compare", session, "--json", "--csv", out)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    assert [i["descents"] for i in res["items"]] == [[1, 4, 5, 8], [2, 3, 6, 7]]
    c = res["comparisons"][0]
    assert (c["a"], c["b"]) == ("pair A / blue", "pair B / blue")
    lo, hi = c["ci90"]
    if differ:
        assert res["ranking"] == ["pair A / blue", "pair B / blue"]
        assert hi < 0 and c["p_a_faster"] > 0.95  # the interval excludes 0
        assert abs(c["delta_mu"] + 0.001) < 0.0002
    else:
        assert lo <= 0 <= hi  # equal skis: the interval includes 0
    assert res["drift"]["separable"] and abs(res["drift"]["mu_per_hour"] - 0.02) < 0.002
    import pandas as pd

    df = pd.read_csv(out, comment="#")
    assert list(df["item"]) == res["ranking"]


@pytest.mark.slow  # a simulated timer on a pty, in real time
def test_compare_flags_windy_descents_and_leaves_out_invalid_ones(tmp_path, run_station):
    session = _record_day(tmp_path, "0.0085,0.0095", seed=5)
    run_station("annotate", session, "--descents", "1,4,5,8", "--ski", "A")
    run_station("annotate", session, "--descents", "2,3,6,7", "--ski", "B")
    r = run_station("annotate", session, "--descents", "3", "--wind-ms", "2.5",
                    "--wind-from-deg", "0")  # fmt: skip
    assert r.returncode == 0
    run_station("annotate", session, "--descents", "6", "--invalid", "edged after PC6")
    r = run_station("compare", session, "--json")
    res = json.loads(r.stdout)
    assert res["excluded"] == [{"descent": 6, "reason": "marked invalid: edged after PC6"}]
    wind3 = along_track_wind(2.5, 0.0, 118.11)
    assert (abs(wind3) > 1.0) == (res["wind_flagged"] == [3])
    r = run_station("compare", session)
    assert "descent 6 left out: marked invalid" in r.stdout


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["--ski", "A"], "give --descents N[,M,A-B] or --from N"),
        (["--descents", "1,x", "--ski", "A"], "'x' is not a descent number"),
        (["--descents", "1"], "nothing to annotate"),
    ],
)
def test_annotate_errors(tmp_path, run_station, args, expect):
    session = tmp_path / "s"
    session.mkdir()
    (session / "raw.jsonl").write_text("")
    r = run_station("annotate", session, *args)
    assert r.returncode == 2 and expect in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run_station("compare", tmp_path / "nothing")
    assert r.returncode == 2 and "not a session directory" in r.stderr


def test_an_item_with_too_few_data_is_a_clear_error(tmp_path, run_station, demo_track):
    data = synthetic(demo_track, "A", {"A": 0.009})[:1]
    short = [DescentData(1, "A", "s", data[0].photocells[:3], data[0].times_s[:3], 10, 88, RHO,
                         0.0, (0.25, 0.02, 3.0))]  # fmt: skip
    from station.model.compare import CompareError

    with pytest.raises(CompareError, match="too few photocells or descents"):
        joint_fit(demo_track, short)
    assert math.isfinite(joint_fit(demo_track, data).items[0].mu)
