"""Fits of finished descents: the station's track, skier and air applied to each timed descent,
and the row of the results CSV it gives. Pure: no I/O, no threads."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

import numpy as np

from station.model.fit import FitResult, fit_descent
from station.model.physics import Conditions, Params, StraightRun
from station.session.config import StationConfig
from station.survey.track import Track
from station.timing.assembly import TimedDescent
from station.timing.impulses import DAY_US


@dataclass
class DescentResult:
    """A descent with its fit and everything the results CSV and the UI show of it."""

    descent: TimedDescent
    fit: FitResult | None
    start_time: str
    row: dict[str, Any]
    speed_x: np.ndarray | None = None  # the fitted skier's speed along the run, for plots
    speed_v: np.ndarray | None = None


class Analyser:
    """Fits finished descents with the station's track, skier and air; grids built once per
    set of photocells."""

    def __init__(self, config: StationConfig, track: Track) -> None:
        self.config = config
        self.track = track
        self._runs: dict[tuple[str, ...], StraightRun] = {}

    def start_time(self, d: TimedDescent, host_t: float | None, date: dt.date | None) -> str:
        day = None
        if host_t is not None:
            day = dt.datetime.fromtimestamp(host_t).date()
        elif date is not None:
            day = date
        days, tod = divmod(d.start_us, DAY_US)
        t = (dt.datetime.min + dt.timedelta(microseconds=tod)).time()
        if day is None:
            return t.isoformat()
        if host_t is None:
            day = day + dt.timedelta(days=days)
        # ISO 8601 with the local UTC offset of that date, so a reader elsewhere (or after the
        # clocks changed) knows the instant: the timer sends local time of day
        return dt.datetime.combine(day, t).astimezone().isoformat()

    def analyse(
        self,
        d: TimedDescent,
        host_t: float | None = None,
        date: dt.date | None = None,
        metadata: dict[str, Any] | None = None,
        model: str | None = None,
        mass_kg: float | None = None,
        air_density: float | None = None,
        wind_ms: float = 0.0,
    ) -> DescentResult:
        cfg = self.config
        meta = {**cfg.metadata, **(metadata or {})}
        model = model or cfg.model
        mass = mass_kg if mass_kg is not None else cfg.mass_kg
        rho = air_density if air_density is not None else cfg.air_density
        fit = None
        if d.status != "aborted":
            ids = tuple(d.photocells)
            run = self._runs.get(ids)
            xs = np.array([self.track.photocell(p).x for p in ids])
            if run is None:
                run = self._runs[ids] = StraightRun(self.track.profile, xs)
            t = (np.array(d.times_us) - d.times_us[0]) / 1e6
            fit = fit_descent(
                self.track.profile,
                xs,
                t,
                Conditions(mass, rho, wind_ms),
                list(ids),
                model=model,
                run=run,
            )
        start = self.start_time(d, host_t, date)
        row = result_row(d, fit, start, meta, model, mass, rho)
        row["wind_ms"] = wind_ms
        res = DescentResult(d, fit, start, row)
        if fit is not None and all(fit.estimates.get(k) is not None for k in ("cda", "mu", "v0")):
            e = fit.estimates
            p = Params(e["cda"], e["mu"], e["v0"], e.get("mu1") or 0.0)  # type: ignore[arg-type]
            sol = run.solve(p, Conditions(mass, rho, wind_ms), sensitivities=False)
            res.speed_x, res.speed_v = sol.x, sol.speed
        return res


def result_row(
    d: TimedDescent,
    fit: FitResult | None,
    start: str,
    meta: dict[str, Any],
    model: str,
    mass_kg: float,
    air_density: float,
) -> dict[str, Any]:
    """One row of the results CSV."""

    def ci(key: str, i: int) -> float | None:
        if fit is None or fit.ci90.get(key) is None:
            return None
        return fit.ci90[key][i]  # type: ignore[index]

    est = fit.estimates if fit else {}
    rms = None
    if fit is not None and fit.residuals_s:
        r = np.array(list(fit.residuals_s.values())[1:])
        rms = float(np.sqrt(np.mean(r**2)) * 1000) if r.size else None
    status = d.status if fit is None else fit.status
    return {
        "descent": d.number,
        "start_time": start,
        "photocells_used": len(d.photocells),
        "missing": " ".join(d.missing),
        "v0": est.get("v0"),
        "cda": est.get("cda"),
        "cda_lo": ci("cda", 0),
        "cda_hi": ci("cda", 1),
        "mu": est.get("mu"),
        "mu_lo": ci("mu", 0),
        "mu_hi": ci("mu", 1),
        "mu1": est.get("mu1") if model == "velocity" else None,
        "sigma_s2": fit.sigma_s2 if fit else None,
        "rms_residual_ms": rms,
        "status": status,
        "descent_status": d.status,
        "flags": "; ".join(d.flags),
        "model": model,
        "mass_kg": mass_kg,
        "air_density": air_density,
        "skier": meta.get("skier", ""),
        "ski": meta.get("ski", ""),
        "wax": meta.get("wax", ""),
        "air_temperature_c": meta.get("air_temperature_c"),
        "snow_temperature_c": meta.get("snow_temperature_c"),
        "pressure_hpa": meta.get("pressure_hpa"),
        "humidity_pct": meta.get("humidity_pct"),
        "notes": meta.get("notes", ""),
        "invalid_reason": "",
    }
