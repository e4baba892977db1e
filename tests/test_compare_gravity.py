"""One gravity (issue 24): the day's comparison uses the g each descent's own fit used (the
site's, from the config's or the survey's latitude), so the site moves an item's μ in
``station compare`` exactly as it moves the per-descent results."""

from __future__ import annotations

import numpy as np
import pytest

from station.model.compare import collect, joint_fit
from station.model.physics import G_STANDARD, Conditions, Params, StraightRun, local_gravity
from station.session.analysis import Analyser, FitJob
from station.session.config import load_config
from station.session.records import DescentStatus, DescentTimes, FitModel, Metadata
from tests.timing_helpers import write_config

RHO = 1.04


def _day(tmp_path, demo_track, demo_xs, extra: str, g_true: float):
    """Four descents (A B A B, μ 0.0085 and 0.0095, noise-free times made with ``g_true``),
    fitted one by one by the station's analyser with the config's site."""
    tmp_path.mkdir()
    cfg = load_config(str(write_config(tmp_path, "loop://", extra=extra)))
    analyser = Analyser(cfg, demo_track)
    run = StraightRun(demo_track.profile, demo_xs)
    out = []
    for k, (ski, mu) in enumerate([("A", 0.0085), ("B", 0.0095), ("A", 0.0085), ("B", 0.0095)]):
        t = run.solve(Params(0.22, mu, 3.0 + 0.2 * k), Conditions(88.0, RHO, g=g_true)).t
        start = 36_000_000_000 + k * 600_000_000  # 10:00, then every 10 minutes
        descent = DescentTimes(
            k + 1, tuple(demo_track.photocell_ids),
            tuple(start + int(round(x * 1e6)) for x in t), DescentStatus.COMPLETE,
        )  # fmt: skip
        job = FitJob(descent, "2026-02-12T10:00:00+00:00", Metadata(ski=ski), FitModel.CONSTANT,
                     88.0, RHO)  # fmt: skip
        out.append(analyser.run(job))
    return out


def test_the_sites_gravity_moves_the_days_mu_as_it_moves_the_descents(
    tmp_path, demo_track, demo_xs
):
    g_site = local_gravity(47.0, 1700.0)
    site = _day(tmp_path / "site", demo_track, demo_xs, "latitude_deg: 47\naltitude_m: 1700\n",
                g_site)  # fmt: skip
    plain = _day(tmp_path / "plain", demo_track, demo_xs, "", g_site)
    assert all(r.row.gravity == pytest.approx(g_site, abs=1e-9) for r in site)
    assert all(r.row.gravity == G_STANDARD for r in plain)

    day_site = joint_fit(demo_track, collect(site).data, drift="off")
    day_plain = joint_fit(demo_track, collect(plain).data, drift="off")
    assert day_site.gravity_ms2 == pytest.approx(g_site, abs=1e-9)
    assert day_site.to_dict()["gravity_ms2"] == pytest.approx(g_site, abs=1e-9)
    for item, truth in (("A", 0.0085), ("B", 0.0095)):
        single_site = np.mean([r.fit.mu.value for r in site if r.row.ski == item])
        single_plain = np.mean([r.fit.mu.value for r in plain if r.row.ski == item])
        # the site's g: the day model gives back the truth, as the single fits do
        assert day_site.item(item).mu == pytest.approx(truth, abs=2e-6)
        assert single_site == pytest.approx(truth, abs=2e-6)
        # standard g biases both the same way (about 1e-4 at 47° N, 1700 m), not one of them
        moved_single = single_plain - single_site
        moved_day = day_plain.item(item).mu - day_site.item(item).mu
        assert abs(moved_single) > 5e-5
        assert moved_day == pytest.approx(moved_single, rel=0.02)


def test_fit_traverse_takes_the_sites_gravity(run_station, tmp_path):
    """fit-traverse has no survey: the site is given, and the g used is in its output."""
    import json

    from station.model.traverse import simulate_traverse

    t = np.linspace(0.0, 6.0, 13)
    g = local_gravity(47.0, 1700.0)
    s = simulate_traverse(t, 0.25, 0.05, 2.0, 25.0, 30.0, 88.0, 1.04, g, 0.0)[0]
    data = tmp_path / "traverse.csv"
    data.write_text("t,s\n" + "".join(f"{a:.4f},{b:.5f}\n" for a, b in zip(t, s, strict=True)))
    base = ["fit-traverse", "--data", str(data), "--slope-deg", "25", "--traverse-deg", "30",
            "--mass", "88", "--air-density", "1.04"]  # fmt: skip
    site = json.loads(run_station(*base, "--latitude-deg", "47", "--altitude-m", "1700",
                                  "--json").stdout)  # fmt: skip
    plain = json.loads(run_station(*base, "--json").stdout)
    assert site["gravity_ms2"] == pytest.approx(g, abs=1e-9)
    assert plain["gravity_ms2"] == G_STANDARD
    assert site["mu"] == pytest.approx(0.05, abs=1e-4)
    assert abs(plain["mu"] - site["mu"]) > 1e-5
    text = run_station(*base, "--latitude-deg", "47").stdout
    assert "GRS80 normal gravity at 47.000°" in text
    alone = run_station(*base, "--altitude-m", "1700")
    assert alone.returncode == 2
    assert alone.stderr.strip().splitlines() == [
        "station: error: field --altitude-m: needs --latitude-deg: normal gravity needs the "
        "site's latitude"
    ]
