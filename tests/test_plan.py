"""`station plan`: the number of descents, the order, the day's length, checked against the
joint fit of `station compare` (its own covariance, and simulated days)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from station.model.compare import joint_fit
from station.model.plan import (
    DayAssumptions,
    delta_mu_of_ms,
    evaluate_design,
    plan_day,
    run_order,
)
from station.simulators.days import DaySetup, simulate_day

SPARSE = ("PC1", "PC3", "PC6", "PC9")


def sparse(track):
    """Four of the demo run's nine photocells: the posture scatter costs descents here."""
    return dataclasses.replace(track, photocells=[p for p in track.photocells if p.id in SPARSE])


def assume(scatter: float, timer_s: float = 5e-4, **kw) -> DayAssumptions:
    base = dict(mass_kg=88.0, air_density=1.079, cda=0.22, v0=3.5, mu=0.0085, timer_sd_s=timer_s,
                posture_sd=scatter, drift_per_hour=0.02, minutes_between=3.0)  # fmt: skip
    base.update(kw)
    return DayAssumptions(**base)  # type: ignore[arg-type]


def test_the_order_is_abba_for_two_items_and_a_mirrored_rotation_for_more():
    letters = "ABCD"
    assert "".join(letters[i] for i in run_order(2, 4)) == "ABBAABBA"
    assert "".join(letters[i] for i in run_order(3, 4)) == "ABCCBAABCCBA"
    # every item's mean position is the same: a linear drift cancels in every comparison
    for n_items in (2, 3, 4):
        order = np.array(run_order(n_items, 4))
        means = [np.mean(np.flatnonzero(order == i)) for i in range(n_items)]
        assert np.ptp(means) == pytest.approx(0.0)


def test_the_plans_standard_error_is_the_joint_fits(demo_track):
    """The plan's covariance and the one the joint fit reports (its own mixed-model equations,
    at the estimated scatter) agree on simulated days of the planned design."""
    tr = sparse(demo_track)
    a = assume(0.01, 1e-3)
    _, se, _ = evaluate_design(tr, 2, 5, 0.001, a)
    order = "".join("AB"[i] for i in run_order(2, 5))
    rng = np.random.default_rng(5)
    reported = []
    for _ in range(8):
        day = DaySetup(scatter=0.01, timer_sd_s=1e-3, v0_range=(3.5, 3.5))
        data = simulate_day(tr, order, {"A": 0.0085, "B": 0.0095}, day, rng)
        reported.append(_delta_se(tr, data))
    assert np.median(reported) == pytest.approx(se, rel=0.2)


def _delta_se(track, data) -> float:
    from scipy.special import stdtrit

    c = joint_fit(track, data).comparisons[0]
    assert c.ci90 is not None and c.dof is not None
    return (c.ci90[1] - c.ci90[0]) / 2 / float(stdtrit(c.dof, 0.95))


def test_more_scatter_or_a_smaller_difference_needs_more_descents(demo_track):
    tr = sparse(demo_track)
    n = {
        (d, s): plan_day(tr, d, assume(s, 1e-3)).descents_per_item
        for d in (0.0005, 0.001)
        for s in (0.005, 0.02)
    }
    assert n[(0.0005, 0.02)] > n[(0.0005, 0.005)] and n[(0.0005, 0.02)] > n[(0.001, 0.02)]
    p = plan_day(tr, 0.0005, assume(0.02, 1e-3))
    assert p.power >= 0.9 > p.power_by_n[p.descents_per_item - 1]
    assert p.order == "".join("AB"[i] for i in run_order(2, p.descents_per_item))
    assert p.minutes == pytest.approx(3.0 * 2 * p.descents_per_item)
    # the expected half-width is what 90 % power asks for: about Δ·1.645/(1.645 + 1.28)
    assert p.halfwidth_mu == pytest.approx(0.0005 * 1.645 / (1.645 + 1.2816), rel=0.1)


def test_delta_in_ms_is_the_run_time_difference(demo_track):
    """--delta-ms: the Δμ found makes the simulated run that many ms slower."""
    from station.model.physics import Conditions, Params, StraightRun

    a = assume(0.01)
    dmu = delta_mu_of_ms(demo_track, 10.0, a)
    run = StraightRun(demo_track.profile, np.array([p.x for p in demo_track.photocells]))

    def t_end(mu):
        return run.solve(Params(0.22, mu, 3.5), Conditions(88.0, 1.079), sensitivities=False).t[-1]

    assert (t_end(0.0085 + dmu) - t_end(0.0085)) * 1e3 == pytest.approx(10.0, rel=0.02)


def test_station_plan_prints_the_plan_and_its_json(run_station, tmp_path):
    r = run_station("plan", "--survey", "surveys/demo_run.yaml", "--mass", "88",
                    "--posture-scatter", "0,015", "--delta-mu", "0,0005", "--air-density",
                    "1.079", "--timer-ms", "0.5", "--drift-per-hour", "0.02")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "3 descents per item, 6 in all, in this order: ABBAAB" in r.stdout  # the least planned
    assert "posture scatter 1.50 % (given)" in r.stdout
    r = run_station("plan", "--survey", "surveys/demo_run.yaml", "--mass", "88",
                    "--posture-scatter", "0.015", "--delta-ms", "5", "--items", "3",
                    "--air-density", "1.079", "--json")  # fmt: skip
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out) >= {"descents_per_item", "order", "minutes", "power", "halfwidth_mu",
                        "assumptions"}  # fmt: skip
    n = out["descents_per_item"]
    assert len(out["order"]) == 3 * n and out["order"].startswith("ABCCBA"[: 3 * n])
    assert out["minutes"] == pytest.approx(3 * n * 3.0) and out["power"] >= 0.9
    assert out["assumptions"]["delta_ms"] == 5 and out["assumptions"]["posture_scatter_pct"] == 1.5


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["--posture-scatter", "1.5", "--delta-mu", "0.001"], "is a fraction of CdA"),
        (["--posture-scatter", "0.01"], "one of the arguments --delta-mu --delta-ms is required"),
        (["--delta-mu", "0.001"], "(--posture-scatter) or a past session (--from)"),
        (["--posture-scatter", "0.01", "--delta-mu", "0.001", "--power", "1.5"], "between 0.5"),
        (["--posture-scatter", "0.01", "--delta-mu", "-1"], "--delta-mu"),
        (["--from", "nowhere", "--delta-mu", "0.001"], "no such session folder"),
    ],
)
def test_station_plan_refuses_bad_input_in_one_line(run_station, args, expect):
    r = run_station("plan", "--survey", "surveys/demo_run.yaml", "--mass", "88",
                    "--air-density", "1.079", *args)  # fmt: skip
    assert r.returncode == 2
    assert expect in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_station_plan_from_a_session_without_scatter_falls_back_to_the_default(
    run_station, tmp_path
):
    """A session whose joint fit puts the posture scatter at 0 (these simulated descents have
    none, and eight descents cannot tell a small one from the timing) is no promise of a steady
    tuck: the plan takes the stated default, 1 %, and says so on stderr; a scatter given wins."""
    from tests.session_helpers import make_session

    session = make_session(tmp_path)
    base = ["plan", "--survey", "surveys/demo_run.yaml", "--mass", "88", "--from", str(session),
            "--delta-mu", "0.001", "--air-density", "1.079", "--json"]  # fmt: skip
    r = run_station(*base)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["assumptions"]["posture_scatter_pct"] == pytest.approx(1.0)
    assert out["assumptions"]["posture_source"].startswith("the default")
    (line,) = r.stderr.strip().splitlines()
    assert line.startswith(f"warning: --from {session}: the session's posture scatter is "
                           "estimated at 0.00 %") and "planning with 1.0 %" in line  # fmt: skip
    r = run_station(*base, "--posture-scatter", "0.02")
    assert r.returncode == 0 and r.stderr == "", r.stderr
    out = json.loads(r.stdout)
    assert out["assumptions"]["posture_scatter_pct"] == pytest.approx(2.0)
    assert out["assumptions"]["posture_source"] == "given"


def test_station_plan_from_a_session_takes_its_drift(run_station, tmp_path):
    """The drift per hour is the session's, as `station compare` estimates it (not the
    default 0), unless --drift-per-hour is given."""
    from tests.session_helpers import make_session

    session = make_session(tmp_path, drift_per_hour=0.004)
    r = run_station("compare", str(session), "--json")
    assert r.returncode == 0, r.stderr
    drift = json.loads(r.stdout)["drift"]["mu_per_hour"]
    assert drift == pytest.approx(0.004, abs=0.001)
    base = ["plan", "--survey", "surveys/demo_run.yaml", "--mass", "88", "--from", str(session),
            "--delta-mu", "0.001", "--json"]  # fmt: skip
    r = run_station(*base)
    assert r.returncode == 0, r.stderr
    a = json.loads(r.stdout)["assumptions"]
    assert a["drift_per_hour"] == pytest.approx(drift, rel=1e-9)
    assert a["drift_source"] == f"estimated from {session}"
    r = run_station(*base, "--drift-per-hour", "0")
    assert r.returncode == 0, r.stderr
    a = json.loads(r.stdout)["assumptions"]
    assert a["drift_per_hour"] == 0 and a["drift_source"] == "given"
    r = run_station(*base[:-1])
    assert r.returncode == 0, r.stderr
    # as compare prints it, not six digits of an estimate ("drift 0.0105534 per hour")
    assert f"drift {drift:.4g} per hour (estimated from {session})" in r.stdout


def test_station_plan_from_a_session_plans_in_its_air(run_station, tmp_path):
    """The CdA taken from a session was fitted in the session's air: without air options the
    plan takes that air too (not the standard 1.290 kg/m³, 20 % more drag at 1.079), and an
    air option given still wins."""
    import pandas as pd

    from tests.session_helpers import make_session

    session = make_session(tmp_path)
    rows = pd.read_csv(session / "results.csv", comment="#")
    rho = float(rows["air_density"].median())
    assert abs(rho - 1.290) > 0.05  # the test would prove nothing in standard air
    base = ["plan", "--survey", "surveys/demo_run.yaml", "--mass", "88", "--from", str(session),
            "--delta-mu", "0.001", "--json"]  # fmt: skip
    r = run_station(*base)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["assumptions"]["air_density"] == pytest.approx(rho, rel=1e-9)
    assert "no air data given" not in r.stderr
    r = run_station(*base, "--air-density", "1.2")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["assumptions"]["air_density"] == pytest.approx(1.2)


@pytest.mark.slow  # a simulation study: 200 simulated days a cell, and 100 at n - 2
@pytest.mark.parametrize(("delta", "scatter"), [(0.001, 0.005), (0.0005, 0.005), (0.0005, 0.01)])
def test_planned_days_resolve_the_difference_with_the_stated_power(demo_track, delta, scatter):
    """Days simulated with the plan's descents and fitted by the real joint fit resolve Δμ with
    the stated power ± 5 % (200 days: binomial SD 2.1 % at 0.9, so a calibrated plan fails one
    cell in 60), and two descents per item fewer do not reach 90 % (the plan is at most one
    larger than needed), checked where the plan itself puts n − 2 at 0.86 or less (closer to
    0.9, 100 days cannot tell). On four photocells, where the scatter costs descents;
    benchmarks/plan_power.py prints the whole table."""
    tr = sparse(demo_track)
    a = assume(scatter, 1e-3, drift_per_hour=DaySetup().drift_per_hour)
    p = plan_day(tr, delta, a)
    n = p.descents_per_item

    def power(per: int, seed: int, days: int) -> float:
        order = "".join("AB"[i] for i in run_order(2, per))
        rng = np.random.default_rng(seed)
        hits = 0
        for _ in range(days):
            data = simulate_day(tr, order, {"A": 0.0085, "B": 0.0085 + delta},
                                DaySetup(scatter=scatter, timer_sd_s=1e-3), rng)  # fmt: skip
            c = joint_fit(tr, data).comparisons[0]
            hits += c.ci90 is not None and c.ci90[1] < 0
        return hits / days

    got = power(n, 1, 200)
    assert abs(got - p.power) <= 0.05, (n, p.power, got)
    if n - 2 >= 2 and evaluate_design(tr, 2, n - 2, delta, a)[0] <= 0.86:
        assert power(n - 2, 2, 100) < 0.9


def test_the_readme_plan_example_is_what_station_plan_prints(run_station):
    """README.md, "Planning the day": the command as typed, its output byte for byte."""
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    block = readme.split("\n$ station plan ", 1)[1].split("\n```", 1)[0]
    command, expected = block.split("\n", 1)
    r = run_station("plan", *command.split())
    assert r.returncode == 0, r.stderr
    assert r.stdout == expected + "\n"


def test_a_power_out_of_reach_is_said(run_station):
    r = run_station("plan", "--survey", "surveys/demo_run.yaml", "--mass", "88",
                    "--posture-scatter", "0.015", "--delta-mu", "0.0001", "--timer-ms", "2",
                    "--air-density", "1.079")  # fmt: skip
    assert r.returncode == 0
    assert "OUT OF REACH" in r.stdout.splitlines()[0]
    assert "90 % power is out of reach within 60 descents per item" in r.stderr
