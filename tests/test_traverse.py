"""Traversing on an inclined plane (paper eq. 22-24) against its closed-form solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from station.model.traverse import fit_traverse, simulate_traverse

G = 9.80665


def closed_form(t, cda, mu, v0, slope, traverse, m, rho):
    """s̈ = a − k ṡ² with a > 0, v0 below the terminal speed: s = ln(cosh(√(ak)t + c)/cosh c)/k."""
    a = G * math.sin(math.radians(slope)) * math.cos(math.radians(traverse))
    a -= mu * G * math.cos(math.radians(slope))
    k = rho * cda / (2 * m)
    c = math.atanh(v0 / math.sqrt(a / k))
    return np.log(np.cosh(math.sqrt(a * k) * t + c) / math.cosh(c)) / k


def test_integration_matches_the_closed_form():
    t = np.linspace(0, 4, 50)
    s, _, jac = simulate_traverse(t, 0.5, 0.1, 1.0, 18, 50, 88, 1.0)
    assert np.max(np.abs(s - closed_form(t, 0.5, 0.1, 1.0, 18, 50, 88, 1.0))) < 1e-9
    # variational equations against central differences of the closed form
    eps = 1e-6
    for j, (dc, dm, dv) in enumerate(((eps, 0, 0), (0, eps, 0), (0, 0, eps))):
        hi = closed_form(t, 0.5 + dc, 0.1 + dm, 1.0 + dv, 18, 50, 88, 1.0)
        lo = closed_form(t, 0.5 - dc, 0.1 - dm, 1.0 - dv, 18, 50, 88, 1.0)
        assert np.max(np.abs((hi - lo) / (2 * eps) - jac[:, j])) < 1e-5


def test_fit_recovers_mu_and_cda_from_precise_positions():
    t = np.linspace(0, 6, 120)
    s = closed_form(t, 0.5, 0.1, 1.0, 25, 30, 88, 1.0) + 2.0
    s = s + np.random.default_rng(3).normal(0, 0.002, len(t))
    res = fit_traverse(t, s, 25, 30, 88, 1.0)
    assert res.status == "ok"
    for k, v in (("cda", 0.5), ("mu", 0.1), ("v0", 1.0), ("s0", 2.0)):
        lo, hi = getattr(res, k).ci90
        assert lo <= v <= hi
    assert res.mu.value == pytest.approx(0.1, abs=0.003)


def test_paper_like_traverse_leaves_cda_unidentified():
    """Upright, 100 frames, ±10 cm positions: μ is found, CdA is not (paper §6.2)."""
    t = np.linspace(0, 4, 100)
    s, _, _ = simulate_traverse(t, 0.6, 0.064, 0.6, 18, 50, 88, 1.0)
    s = s + np.random.default_rng(0).normal(0, 0.1, len(t))
    res = fit_traverse(t, s, 18, 50, 88, 1.0)
    assert res.status == "ill-conditioned"
    assert res.cda.value is None and res.cda.ci90 is None
    lo, hi = res.mu.ci90
    assert lo <= 0.064 <= hi and hi - lo < 0.05
