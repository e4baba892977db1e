"""fit-traverse: the angle from the fall line or from the horizontal, and the output says which."""

from __future__ import annotations

import json

import numpy as np
import pytest

from station.model.traverse import simulate_traverse

AIR = ["--air-density", "1.0"]


@pytest.fixture
def data(tmp_path):
    t = np.linspace(0, 4, 60)
    s, _, _ = simulate_traverse(t, 0.5, 0.1, 1.0, 25, 50, 88, 1.0)  # β = 50° from the fall line
    path = tmp_path / "tr.csv"
    path.write_text("t,s\n" + "\n".join(f"{a:.4f},{b:.5f}" for a, b in zip(t, s, strict=True)))
    return path


def test_angle_from_the_horizontal_is_converted(run_station, data):
    base = ["fit-traverse", "--data", data, "--slope-deg", "25", "--mass", "88", *AIR, "--json"]
    a = json.loads(run_station(*base, "--traverse-deg", "50").stdout)
    b = json.loads(run_station(*base, "--traverse-from-horizontal-deg", "40").stdout)
    assert a["mu"] == pytest.approx(0.1, abs=1e-4) and b["mu"] == pytest.approx(a["mu"])
    assert a["traverse_given_as"] == "from the fall line"
    assert b["traverse_given_as"] == "from the horizontal"
    assert b["traverse_from_fall_line_deg"] == 50.0
    # the paper's trap: 40 entered as if from the fall line gives a very different μ
    c = json.loads(run_station(*base, "--traverse-deg", "40").stdout)
    assert abs(c["mu"] - 0.1) > 0.02
    text = run_station(*base[:-1], "--traverse-from-horizontal-deg", "40").stdout
    assert "traverse 50° from the fall line (given as 40° from the horizontal)" in text


def test_angle_options_exclusive_and_documented(run_station, data):
    base = ["fit-traverse", "--data", data, "--slope-deg", "25", "--mass", "88", *AIR]
    r = run_station(*base, "--traverse-deg", "50", "--traverse-from-horizontal-deg", "40")
    assert r.returncode == 2 and "not allowed with" in r.stderr
    r = run_station(*base)
    assert r.returncode == 2 and "required" in r.stderr
    r = run_station(*base, "--traverse-deg", "95")
    assert r.returncode == 2 and "between 0 and 90" in r.stderr
    h = " ".join(run_station("fit-traverse", "--help").stdout.split())
    assert "measured from the fall line" in h and "from the horizontal" in h
