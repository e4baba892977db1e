"""The state of a test day: descents, their fits, and what the engineer said about them.

Metadata typed at the trackside (skier, mass, ski, wax, air and snow temperature, pressure,
humidity, notes) applies to the descents that start after it was entered. A descent can be
marked invalid with a reason, or refitted with another model. Those *annotations* are stored
beside the raw log (``annotations.jsonl``) and applied again in replay, so a replayed session
gives the same results as the live one. Pure: no I/O, no threads (callers hold a lock).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field
from typing import Any

from station.errors import InputError
from station.model.air import air_density
from station.session.analysis import Analyser, DescentResult
from station.session.config import StationConfig
from station.session.processor import Processor
from station.survey.track import Track
from station.timing.assembly import TimedDescent

#: metadata keys the UI edits, with their types
METADATA_FIELDS: dict[str, type] = {
    "skier": str,
    "mass_kg": float,
    "ski": str,
    "wax": str,
    "air_temperature_c": float,
    "snow_temperature_c": float,
    "pressure_hpa": float,
    "humidity_pct": float,
    "wind_ms": float,
    "wind_from_deg": float,
    "notes": str,
}


def along_track_wind(speed_ms: float, from_deg: float | None, track_azimuth_deg: float) -> float:
    """The wind component along the run, + tailwind (blowing downhill), − headwind.

    ``from_deg`` is where the wind comes from (meteorological convention, degrees from grid
    north); it blows toward ``from_deg + 180``. A speed without a direction is refused: taken as
    full tailwind, a 2 m/s cross wind moved μ by 0.006–0.008 (issue 12).
    """
    if from_deg is None:
        raise ValueError("a wind speed needs the direction it comes from (wind_from_deg)")
    toward = math.radians(from_deg + 180.0 - track_azimuth_deg)
    return speed_ms * math.cos(toward)


@dataclass
class Day:
    """Processor + analyser + annotations; ``results`` keyed by descent number."""

    config: StationConfig
    track: Track
    processor: Processor
    analyser: Analyser
    date: dt.date | None = None
    results: dict[int, DescentResult] = field(default_factory=dict)
    metadata_changes: list[tuple[int, dict[str, Any]]] = field(default_factory=list)
    metadata_for_descents: list[tuple[set[int], dict[str, Any]]] = field(default_factory=list)
    invalid: dict[int, str] = field(default_factory=dict)
    models: dict[int, str] = field(default_factory=dict)

    @classmethod
    def start(cls, config: StationConfig, track: Track, date: dt.date | None = None) -> Day:
        return cls(config, track, Processor(config, track), Analyser(config, track), date)

    # -- metadata

    def base_metadata(self) -> dict[str, Any]:
        cfg = self.config
        meta: dict[str, Any] = {"mass_kg": cfg.mass_kg, **cfg.metadata}
        if "pressure_hpa" in cfg.air:
            meta["pressure_hpa"] = cfg.air["pressure_hpa"]
            meta["air_temperature_c"] = cfg.air["temperature_c"]
            meta["humidity_pct"] = cfg.air["humidity_pct"]
        return meta

    def metadata_for(self, number: int) -> dict[str, Any]:
        """Metadata in force for a descent: the config's, then the changes ``from`` a number on
        in the order they were made, then those for listed descents only (the most specific)."""
        meta = self.base_metadata()
        for start, values in self.metadata_changes:
            if start <= number:
                meta.update(values)
        for descents, values in self.metadata_for_descents:
            if number in descents:
                meta.update(values)
        return meta

    def wind_for(self, meta: dict[str, Any]) -> float:
        if "wind_ms" not in meta:
            return 0.0
        if meta.get("wind_from_deg") is None and float(meta["wind_ms"]) != 0.0:
            raise InputError(
                f"wind {meta['wind_ms']:g} m/s without a direction: give the direction it comes "
                "from (wind_from_deg), or no wind",
                field="wind_from_deg",
            )
        if meta.get("wind_from_deg") is None:
            return 0.0
        return along_track_wind(
            float(meta["wind_ms"]), meta.get("wind_from_deg"), self.track.azimuth_deg
        )

    def next_number(self) -> int:
        """The number the next descent to start will get (an open one is already counted)."""
        return self.processor.assembler.count + 1

    def density_for(self, meta: dict[str, Any]) -> float:
        """Air density from the descent's metadata where it has P, T, RH; else the config's."""
        air = self.config.air
        if "density" in air and not any(k in meta for k in ("pressure_hpa", "air_temperature_c")):
            return self.config.air_density
        p = meta.get("pressure_hpa", air.get("pressure_hpa"))
        t = meta.get("air_temperature_c", air.get("temperature_c"))
        h = meta.get("humidity_pct", air.get("humidity_pct", 80.0))
        if p is None or t is None:
            return self.config.air_density
        return air_density(float(p), float(t), float(h))

    # -- descents

    def analyse(self, d: TimedDescent) -> DescentResult:
        meta = self.metadata_for(d.number)
        res = self.analyser.analyse(
            d,
            self.processor.start_host.get(d.number),
            self.date,
            metadata=meta,
            model=self.models.get(d.number),
            mass_kg=float(meta.get("mass_kg", self.config.mass_kg)),
            air_density=self.density_for(meta),
            wind_ms=self.wind_for(meta),
        )
        res.row["invalid_reason"] = self.invalid.get(d.number, "")
        self.results[d.number] = res
        return res

    def finish(self, done: list[TimedDescent]) -> list[DescentResult]:
        return [self.analyse(d) for d in done]

    def rows(self) -> list[dict[str, Any]]:
        return [self.results[k].row for k in sorted(self.results)]

    # -- annotations

    def annotate(self, record: dict[str, Any]) -> DescentResult | None:
        """Apply one annotation; returns the descent result it changed, if any."""
        kind = record.get("type")
        if kind == "metadata":
            values = {k: v for k, v in record.get("values", {}).items() if k in METADATA_FIELDS}
            if "descents" in record:
                numbers = {int(n) for n in record["descents"]}
                self.metadata_for_descents.append((numbers, values))
                for n in sorted(numbers):  # already fitted: fit again with the new metadata
                    if n in self.results:
                        self.analyse(self.results[n].descent)
                return None
            self.metadata_changes.append((int(record["from"]), values))
            return None
        n = int(record.get("descent", 0))
        if kind == "invalid":
            self.invalid[n] = str(record.get("reason", "")) or "marked invalid"
        elif kind == "valid":
            self.invalid.pop(n, None)
        elif kind == "model":
            self.models[n] = str(record.get("model", "constant"))
        else:
            return None
        res = self.results.get(n)
        if res is None:
            return None
        if kind == "model":
            return self.analyse(res.descent)
        res.row["invalid_reason"] = self.invalid.get(n, "")
        return res
