"""The survey covariance of a recorded day, computed once at a reference fit (the config's
model, mass and air: station/session/analysis.py, ``Analyser``), against each descent's own
(at its own fit, 15 ms a descent): how much the 90 % intervals of μ and CdA differ.

A day of 8 descents is made as tests/session_helpers.py makes them (skier 88 kg, the config's
88 kg); then annotated so that every fit differs from the reference: another mass from
descent 1 on, measured air (800 hPa, −15 °C), and a model. Printed: the largest relative
difference of a 90 % half-width of μ and CdA, and of v0, at descent 1 (the reference point
alone: its own times at another mass, air or model) and at descents 2–8 (the covariance of
descent 1's times handed to other descents, as before the reference fit); and the time of
one fit with the covariance given and with its own computed. A 90 % interval the survey does
not widen (the timing-only one is wider: station.model.track_error) differs by nothing.

Run: python benchmarks/survey_reference.py
"""

from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.model.fit import fit_descent  # noqa: E402
from station.model.physics import Conditions  # noqa: E402
from station.model.track_error import survey_error  # noqa: E402
from station.session import store  # noqa: E402
from station.session.records import FitModel, Metadata, MetadataAnnotation, ModelChange  # noqa: E402
from station.session.runs import replay  # noqa: E402
from tests.session_helpers import make_session  # noqa: E402

CASES = [(60.0, FitModel.CONSTANT), (110.0, FitModel.CONSTANT), (88.0, FitModel.VELOCITY)]


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        source = make_session(Path(tmp), order="ABBAABBA", annotate=False)
        for mass, model in CASES:
            session = Path(tmp) / f"{mass:g}-{model.value}"
            shutil.copytree(source, session)
            meta = Metadata(mass_kg=mass, pressure_hpa=800.0, air_temperature_c=-15.0)
            store.append_annotation(str(session), MetadataAnnotation(meta, from_descent=1, t=1.0))
            for n in range(1, 9):
                store.append_annotation(str(session), ModelChange(n, model, 2.0))
            day = replay(
                str(session), store.load_session_config(str(session)), speed_curves=False
            ).day
            an = day.analyser
            worst = {(at, k): 0.0 for at in ("ref", "on") for k in ("mu/cda", "v0")}
            given, own_s = [], []
            for r in day.results.values():
                job = day.fit_job(r.descent)
                ids = list(r.descent.photocells)
                xs = np.array([an.track.photocell(p).x for p in ids])
                t = (np.array(r.descent.times_us) - r.descent.times_us[0]) / 1e6
                cond = Conditions(job.mass_kg, job.air_density, job.wind_ms, g=an.gravity.value)
                t0 = time.perf_counter()
                own = fit_descent(an.track.profile, xs, t, cond, ids, model=model.value,
                                  survey=survey_error(an.track, ids))  # fmt: skip
                own_s.append(time.perf_counter() - t0)
                fit = r.fit
                assert fit is not None
                t0 = time.perf_counter()
                fit_descent(an.track.profile, xs, t, cond, ids, model=model.value,
                            survey_time_cov=fit.survey_time_cov)  # fmt: skip
                given.append(time.perf_counter() - t0)
                at = "ref" if r.number == an.survey_source[r.descent.photocells] else "on"
                for k in ("mu", "cda", "v0"):
                    a, b = getattr(fit, k).ci90, getattr(own, k).ci90
                    if a is not None and b is not None:
                        rel = abs((a[1] - a[0]) - (b[1] - b[0])) / (b[1] - b[0])
                        w = (at, "v0" if k == "v0" else "mu/cda")
                        worst[w] = max(worst[w], rel)
            print(
                f"skier {mass:5.1f} kg (config 88), air annotated, model {model.value:8s}: "
                f"90 % half-widths of μ, CdA differ by at most {worst['ref', 'mu/cda']:.3%} "
                f"at the reference descent, {worst['on', 'mu/cda']:.3%} at the others (v0: "
                f"{worst['ref', 'v0']:.3%}, {worst['on', 'v0']:.3%}); one fit "
                f"{statistics.median(given) * 1e3:.1f} ms with the covariance given, "
                f"{statistics.median(own_s) * 1e3:.1f} ms computing its own"
            )


if __name__ == "__main__":
    main()
