"""Test-day analysis: the joint fit, comparisons, drift, wind, and the proof of the issue."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from reference_dae import simulate_dae

from station.model.batch import Rows, solve_rows
from station.model.compare import DescentData, joint_fit
from station.model.compare_reml import Pieces, linear_step
from station.model.fit import fit_descent
from station.model.physics import Conditions, Params, StraightRun
from station.report.comparison_text import format_comparison
from station.session.day import along_track_wind
from tests.timing_helpers import record_with_sim

RHO = 1.079


def synthetic(demo_track, order: str, mus: dict[str, float], drift_per_hour=0.0, seed=0,
              noise_s=5e-4, step_h=0.05, scatter=0.0) -> list[DescentData]:  # fmt: skip
    """A simulated day; ``scatter``: the SD of log CdA between descents (posture)."""
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    rng = np.random.default_rng(seed)
    out = []
    for k, item in enumerate(order):
        mu = mus[item] + drift_per_hour * k * step_h
        cda = 0.22 * float(np.exp(rng.normal(0.0, scatter))) if scatter else 0.22
        t = run.solve(
            Params(cda, mu, rng.uniform(2.5, 4.5)), Conditions(88, RHO), sensitivities=False
        ).t
        t = np.round(t + rng.normal(0, noise_s, len(t)), 4)
        out.append(DescentData(k + 1, item, "skier", tuple(demo_track.photocell_ids), t - t[0],
                               10 + k * step_h, 88.0, RHO, 0.0, (0.25, 0.02, 3.0)))  # fmt: skip
    return out


def test_two_items_are_told_apart_and_drift_is_corrected(demo_track):
    data = synthetic(demo_track, "ABBAABBA", {"A": 0.0085, "B": 0.0095}, drift_per_hour=0.02)
    res = joint_fit(demo_track, data)
    assert res.ranking == ("A", "B")
    c = res.comparisons[0]
    assert (c.a, c.b) == ("A", "B")
    assert c.ci90[1] < 0 and c.ci90[0] <= -0.001 <= c.ci90[1] and c.p_a_faster > 0.99
    d, (lo, hi) = res.drift_per_hour
    assert lo <= 0.02 <= hi and res.drift_separable
    assert res.cda["skier"].value == pytest.approx(0.22, abs=0.002)


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
    cda = res.cda["skier"].value
    ta = simulate_dae(demo_track.profile, xs, Params(cda, a, res.typical_v0), Conditions(88, RHO)).t
    tb = simulate_dae(demo_track.profile, xs, Params(cda, b, res.typical_v0), Conditions(88, RHO)).t
    assert c.delta_t_s == pytest.approx(ta[-1] - tb[-1], abs=1e-6)
    assert -0.05 < c.delta_t_s < -0.01  # 0.001 in μ is some 30 ms over 344 m


def test_along_track_wind_and_its_effect_on_the_fit(demo_track):
    az = demo_track.azimuth_deg
    assert along_track_wind(3.0, az + 180.0, az) == pytest.approx(3.0)  # from uphill: tailwind
    assert along_track_wind(3.0, az, az) == pytest.approx(-3.0)  # from downhill: headwind
    assert along_track_wind(3.0, az + 90.0, az) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="direction"):
        along_track_wind(3.0, None, az)  # a speed alone is not a tailwind
    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, RHO, 2.0))
        .t
    )
    right = fit_descent(demo_track.profile, xs, t, Conditions(88, RHO, 2.0))
    wrong = fit_descent(demo_track.profile, xs, t, Conditions(88, RHO, 0.0))
    assert right.mu.value == pytest.approx(0.0085, abs=1e-6)
    assert abs(wrong.mu.value - 0.0085) > 5e-4 or abs(wrong.cda.value - 0.22) > 0.02


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
        (["--descents", "1", "--wind-ms", "2"], "--wind-ms needs --wind-from-deg"),
    ],
)
def test_annotate_errors(tmp_path, run_station, args, expect):
    session = tmp_path / "s"
    session.mkdir()
    (session / "raw.jsonl").write_text("")
    r = run_station("annotate", session, *args)
    assert r.returncode == 2 and expect in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run_station("compare", tmp_path / "nothing")
    assert r.returncode == 2 and "no such session folder" in r.stderr


def test_an_item_with_too_few_data_is_a_clear_error(tmp_path, run_station, demo_track):
    data = synthetic(demo_track, "A", {"A": 0.009})[:1]
    short = [DescentData(1, "A", "s", data[0].photocells[:3], data[0].times_s[:3], 10, 88, RHO,
                         0.0, (0.25, 0.02, 3.0))]  # fmt: skip
    from station.model.compare import CompareError

    with pytest.raises(CompareError, match="too few photocells or descents"):
        joint_fit(demo_track, short)
    assert math.isfinite(joint_fit(demo_track, data).items[0].mu)


def test_posture_scatter_is_estimated_from_the_day(demo_track):
    """Sixteen descents with 2 % posture scatter: the estimate is near 2 % and its interval
    holds it; without scatter the estimate is small."""
    order = "ABBAABBAABBAABBA"
    mus = {"A": 0.0085, "B": 0.0095}
    res = joint_fit(demo_track, synthetic(demo_track, order, mus, 0.02, seed=7, scatter=0.02))
    assert 0.012 < res.posture_sd < 0.03
    lo, hi = res.posture_ci90
    assert lo <= 0.02 <= hi
    assert "posture scatter" in format_comparison(res, 16)
    assert res.to_dict()["posture_sd_pct"] == pytest.approx(100 * res.posture_sd)
    still = joint_fit(demo_track, synthetic(demo_track, order, mus, 0.02, seed=7))
    assert still.posture_sd < 0.004
    # each descent's own drag area follows its posture
    assert len(res.descents) == 16 and all(0.2 < d.cda < 0.24 for d in res.descents)


@pytest.mark.slow
def test_delta_mu_intervals_hold_with_posture_scatter(demo_track):
    """2 % posture scatter (issue 12: 34 % coverage with one CdA per skier): over 100 simulated
    days the 90 % interval of Δμ holds the truth about nine times in ten and names the wrong
    ski as faster no more often than its 5 % tail allows. The full table (200 days per level):
    benchmarks/compare_calibration.py."""
    n = 100
    hits = wrong = 0
    for seed in range(n):
        data = synthetic(demo_track, "ABBAABBA", {"A": 0.0085, "B": 0.0095}, 0.02,
                         seed=100 + seed, scatter=0.02)  # fmt: skip
        lo, hi = joint_fit(demo_track, data).comparisons[0].ci90
        hits += lo <= -0.001 <= hi
        wrong += lo > 0
    assert 0.82 <= hits / n <= 0.97, hits
    assert wrong <= 6, wrong


def test_one_descent_per_item_allows_no_comparison(demo_track):
    data = synthetic(demo_track, "AB", {"A": 0.0085, "B": 0.0095}, noise_s=1e-4)
    res = joint_fit(demo_track, data)
    c = res.comparisons[0]
    assert c.ci90 is None and c.p_a_faster is None and "no comparison possible" in c.note
    assert all(i.p_best is None for i in res.items)
    text = format_comparison(res, 2)
    assert "no comparison possible" in text and "P(A faster)" not in text
    assert any("one descent each" in w for w in res.warnings)


def test_p_best_for_every_item(demo_track):
    data = synthetic(demo_track, "ABCCBAABCCBA", {"A": 0.0085, "B": 0.0095, "C": 0.0090},
                     0.02, seed=2)  # fmt: skip
    res = joint_fit(demo_track, data)
    p = {i.item: i.p_best for i in res.items}
    assert sum(p.values()) == pytest.approx(1.0)
    assert p["A"] > 0.9 and p["B"] < 0.05 and p["A"] >= p["C"] >= p["B"]
    assert len(res.comparisons) == 3
    assert res.item("A").p_best == p["A"]


def test_the_day_result_is_built_once(demo_track):
    """Left-out and wind-flagged descents go in, not onto the result afterwards."""
    import dataclasses

    data = synthetic(demo_track, "ABBA", {"A": 0.0085, "B": 0.0095})
    res = joint_fit(demo_track, data, excluded=[(5, "marked invalid: fell")], wind_flagged=[2],
                    wind_limit_ms=1.0)  # fmt: skip
    assert res.excluded == ((5, "marked invalid: fell"),) and res.wind_flagged == (2,)
    assert any("descents 2 had more than 1 m/s" in w for w in res.warnings)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.status = "ok"  # type: ignore[misc]
    assert isinstance(res.warnings, tuple) and isinstance(res.items, tuple)


def test_residuals_the_timer_cannot_explain_are_a_poor_fit(demo_track):
    """3 ms of noise judged against a 0.5 ms timer: flagged, not "ok"; the same day judged
    against a 3 ms timer is fine."""
    data = synthetic(demo_track, "ABBAABBA", {"A": 0.0085, "B": 0.0095}, 0.02, noise_s=3e-3)
    res = joint_fit(demo_track, data, timer_sd_s=5e-4)
    assert res.status == "poor-fit" and res.chi2_p < 1e-3
    assert "POOR FIT" in format_comparison(res, 8) and "timer" in res.message
    assert joint_fit(demo_track, data, timer_sd_s=3e-3).status == "ok"


def test_the_block_elimination_is_the_dense_least_squares_solution():
    """The Schur-complement step, PRSS and log det equal those of the dense penalised problem
    solved directly (an independent formulation)."""
    rng = np.random.default_rng(0)
    d, n, g, wu = 5, 7, 3, 4.0
    a = rng.normal(size=(d, n, g))
    b = rng.normal(size=(d, n, 3))
    r = rng.normal(size=(d, n))
    u = rng.normal(size=d)
    pc = Pieces(
        bb=np.einsum("dni,dnj->dij", b, b), ab=np.einsum("dng,dni->dgi", a, b),
        aa=np.einsum("dng,dnh->gh", a, a), br=np.einsum("dni,dn->di", b, r),
        ar=np.einsum("dng,dn->g", a, r), a=a, b=b, r=r, u=u,
    )  # fmt: skip
    st = linear_step(pc, wu)
    # dense: rows of times, then one penalty row per descent on its u
    big = np.zeros((d * n + d, g + 3 * d))
    rhs = np.zeros(d * n + d)
    for k in range(d):
        big[k * n : (k + 1) * n, :g] = a[k]
        big[k * n : (k + 1) * n, g + 3 * k : g + 3 * k + 3] = b[k]
        rhs[k * n : (k + 1) * n] = -r[k]
        big[d * n + k, g + 3 * k] = math.sqrt(wu)
        rhs[d * n + k] = -math.sqrt(wu) * u[k]
    step, *_ = np.linalg.lstsq(big, rhs, rcond=None)
    assert np.allclose(st.dg, step[:g]) and np.allclose(st.dl.ravel(), step[g:])
    assert st.prss == pytest.approx(float(np.sum((big @ step - rhs) ** 2)))
    assert st.logdet == pytest.approx(np.linalg.slogdet(big.T @ big)[1])


@pytest.mark.parametrize(
    ("mu1", "wind", "n_params"), [(0.0, 0.0, 3), (8e-5, 0.0, 4), (0.0, 1.5, 3)]
)
def test_the_batch_solver_agrees_with_the_dae(demo_track, mu1, wind, n_params):
    """All descents of a day solved at once give the times of the independent Cartesian DAE,
    and the sensitivities of the one-descent solver."""
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    rng = np.random.default_rng(1)
    n = 40  # more than a chunk
    cda, mu, v0 = rng.uniform(0.18, 0.26, n), rng.uniform(0.005, 0.012, n), rng.uniform(2, 5, n)
    mass = rng.uniform(70, 95, n)
    sol = solve_rows(run, Rows(cda, mu, v0, np.full(n, mu1), RHO / mass, np.full(n, wind),
                               9.80665), n_params)  # fmt: skip
    for i in (0, 33):
        p, c = Params(cda[i], mu[i], v0[i], mu1), Conditions(mass[i], RHO, wind)
        ref = simulate_dae(demo_track.profile, xs, p, c)
        assert np.max(np.abs(sol.t[i] - ref.t)) < 1e-6
        one = run.solve(p, c, n_params)
        assert np.allclose(sol.dt_dp[i], one.dt_dp, rtol=1e-9, atol=1e-12)
    assert sol.converged.all() and not sol.stopped.any()
