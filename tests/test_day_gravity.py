"""The day's fits use the same local gravity as ``station fit``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from station.model.physics import Conditions, Params, StraightRun, local_gravity
from station.session.analysis import Analyser, FitJob
from station.session.records import DescentStatus, DescentTimes, FitModel, Metadata


def test_the_days_fits_use_the_surveys_latitude(demo_track, demo_xs):
    track = dataclasses.replace(demo_track, latitude_deg=47.0)
    g = local_gravity(47.0, track.mean_height_m)
    truth = Params(0.22, 0.0085, 3.4)
    t = StraightRun(track.profile, demo_xs).solve(truth, Conditions(88.0, 1.04, g=g)).t
    descent = DescentTimes(
        1, tuple(track.photocell_ids), tuple(int(round(x * 1e6)) for x in t),
        DescentStatus.COMPLETE,
    )  # fmt: skip
    job = FitJob(descent, "2026-02-12T10:00:00+00:00", Metadata(), FitModel.CONSTANT, 88.0, 1.04)
    analyser = Analyser(None, track)  # type: ignore[arg-type]
    assert analyser.gravity.value == pytest.approx(g) and "GRS80" in analyser.gravity.source
    res = analyser.run(job)
    fit = res.fit
    assert res.row.gravity == pytest.approx(g)  # the results and the UI say which g was used
    assert fit is not None and fit.mu.value == pytest.approx(0.0085, abs=2e-6)
    # standard gravity on the same times: μ off by about (g0 − g)/g·(tan α − μ)
    plain = Analyser(None, demo_track).run(job).fit  # type: ignore[arg-type]
    assert abs(plain.mu.value - 0.0085) > 5e-5
    assert np.isfinite(plain.mu.value)
