"""Raw chunks -> lines -> impulses -> descents -> fits -> result rows, with no I/O.

The same :class:`Processor` runs live (fed by the serial reader after each chunk is logged)
and in replay (fed from the raw log or a plain capture), so a replay reproduces the live
results exactly. Time-outs are the one thing that depends on the clock rather than on the
bytes. A live time-out is written to the raw log as a ``timeout`` event, and replay applies
it from there. Impulse-driven endings (the next start, the last photocell, an impulse after
the time-out) need no clock at all.
"""

from __future__ import annotations

import datetime as dt
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from station.config import StationConfig
from station.descents import Descent, DescentAssembler, ImpulseEvent
from station.errors import InputError
from station.fit import FitResult, fit_descent
from station.framing import LineFramer
from station.impulse import DAY_US, Edit, Impulse, Skip, Unparsed
from station.physics import Conditions, Params, StraightRun
from station.protocols import make_parser
from station.rawlog import Chunk
from station.track import Track


class Processor:
    """Bytes in, finished descents out; counts every kind of line on the way."""

    def __init__(self, config: StationConfig, track: Track) -> None:
        known = set(track.photocell_ids)
        for ch, pc in config.channels.items():
            if pc not in known:
                raise InputError(
                    f"photocell {pc!r} is not in the survey ({', '.join(track.photocell_ids)})",
                    path=config.path,
                    field=f"photocells.{ch}",
                )
        self.parser = make_parser(config.serial.protocol)
        self.framer = LineFramer()
        positions = [
            track.profile.arc_length(track.photocells[0].x, pc.x) for pc in track.photocells
        ]
        self.assembler = DescentAssembler(
            track.photocell_ids,
            config.channels,
            debounce_s=config.descent.debounce_s,
            timeout_s=config.descent.timeout_s,
            positions_m=positions,
            min_speed_ms=config.descent.min_speed_ms,
        )
        self.lines = 0
        self.counts: Counter[str] = Counter()
        self.unparsed: list[tuple[int, str, str]] = []  # line number, reason, text (first 100)
        self.connection: list[tuple[float, str, str]] = []
        self.offset_us: int | None = None  # device clock − host clock
        self.start_host: dict[int, float | None] = {}

    @property
    def events(self) -> list[ImpulseEvent]:
        return self.assembler.events

    def feed(self, chunk: Chunk) -> list[Descent]:
        if chunk.event:
            if chunk.event == "timeout":
                return self.tick(chunk.t)
            if chunk.event != "session":
                self.connection.append((chunk.t, chunk.event, chunk.detail))
            return []
        done: list[Descent] = []
        for line in self.framer.feed(chunk.data):
            done += self._line(line, chunk.t)
        return done

    def _line(self, line: str, t: float | None) -> list[Descent]:
        self.lines += 1
        parsed = self.parser.parse(line)
        if isinstance(parsed, Impulse):
            self.counts["impulse"] += 1
            before = self.assembler.count
            done = self.assembler.feed(parsed, self.lines)
            if t is not None and self.assembler._clock is not None:
                self.offset_us = self.assembler._clock - round(t * 1e6)
            if self.assembler.count > before:
                self.start_host[self.assembler.count] = t
            return done
        if isinstance(parsed, Edit):
            self.counts["edit"] += 1
            self.assembler.events.append(
                ImpulseEvent(
                    self.lines,
                    parsed.channel,
                    self.assembler.channels.get(parsed.channel),
                    parsed.tod_us,
                    parsed.flag,
                    False,
                    f"{parsed.kind}: repeats an earlier impulse, not a new one",
                )
            )
        elif isinstance(parsed, Skip):
            self.counts["skipped"] += 1
        elif isinstance(parsed, Unparsed):
            self.counts["unparsed"] += 1
            if len(self.unparsed) < 1000:
                self.unparsed.append((self.lines, parsed.reason, line[:100]))
        return []

    def tick(self, host_t: float) -> list[Descent]:
        """Host time now: end a descent whose time-out passed on the device clock."""
        if self.offset_us is None:
            return []
        return self.assembler.tick(round(host_t * 1e6) + self.offset_us)

    def finish(self) -> list[Descent]:
        """End of the input: the unfinished last line, then the open descent."""
        done: list[Descent] = []
        for line in self.framer.flush():
            done += self._line(line, None)
        return done + self.assembler.close()


@dataclass
class DescentResult:
    """A descent with its fit and everything the results CSV and the UI show of it."""

    descent: Descent
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

    def start_time(self, d: Descent, host_t: float | None, date: dt.date | None) -> str:
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
        return dt.datetime.combine(day, t).isoformat()

    def analyse(
        self,
        d: Descent,
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
    d: Descent,
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
