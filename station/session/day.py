"""The state of a test day: descents, their fits, and what the engineer said about them.

Metadata typed at the trackside (skier, mass, ski, wax, air and snow temperature, pressure,
humidity, wind, notes: :class:`station.session.records.Metadata`) applies to the descents that
start after it was entered. A descent can be marked invalid with a reason, or refitted with
another model. Those *annotations* are stored beside the raw log (``annotations.jsonl``) and
applied again in replay, so a replayed session gives the same results as the live one.

An invalid mark is stored once, in ``invalid``; the results the day hands out carry it as a
view (:meth:`Day.snapshot`). Pure: no I/O, no threads (the acquisition loop holds a lock).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field

from station.errors import InputError
from station.model.air import air_density
from station.model.timer import precision_from_resolution
from station.session.analysis import Analyser, DescentResult, FitJob, start_time
from station.session.config import StationConfig
from station.session.marks import Marks
from station.session.processor import Processor
from station.session.records import (
    METADATA_FIELDS,
    Annotation,
    DescentTimes,
    FitModel,
    Metadata,
    MetadataAnnotation,
    ModelChange,
    Progress,
)
from station.survey.track import Track

__all__ = ["METADATA_FIELDS", "Day", "Effect", "along_track_wind"]


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


#: distinct metadata a day shares among its descents (beyond: each its own, as before)
MAX_METADATA = 4096


@dataclass(frozen=True)
class Effect:
    """What an annotation changed: descents to fit again, and results whose mark changed."""

    refit: tuple[int, ...] = ()
    changed: tuple[int, ...] = ()


@dataclass
class Day:
    """Processor + analyser + annotations; ``results`` (fits, keyed by descent number)."""

    config: StationConfig
    track: Track
    processor: Processor
    analyser: Analyser
    date: dt.date | None = None
    results: dict[int, DescentResult] = field(default_factory=dict)
    _marks: Marks | None = field(default=None, repr=False)  # built at first use (the config's)
    #: the metadata of the descents fitted, one object for equal ones: a change "from descent
    #: N on" made a new one for every later descent, each kept with its row all day
    _metas: dict[Metadata, Metadata] = field(default_factory=dict, repr=False)

    @classmethod
    def start(cls, config: StationConfig, track: Track, date: dt.date | None = None) -> Day:
        return cls(config, track, Processor(config, track), Analyser(config, track), date)

    # -- metadata

    @property
    def marks(self) -> Marks:
        """The annotations as they stand (:class:`station.session.marks.Marks`: the same rules
        as the in-place annotate's)."""
        if self._marks is None:
            self._marks = Marks.of(self.config)
        return self._marks

    @property
    def invalid(self) -> dict[int, str]:
        return self.marks.invalid

    @property
    def models(self) -> dict[int, FitModel]:
        return self.marks.models

    def base_metadata(self) -> Metadata:
        return self.marks.base

    def metadata_for(self, number: int) -> Metadata:
        """Metadata in force for a descent (:meth:`station.session.marks.Marks.metadata_for`)."""
        return self.marks.metadata_for(number)

    def wind_for(self, meta: Metadata) -> float:
        if meta.wind_ms is None:
            return 0.0
        if meta.wind_from_deg is None and meta.wind_ms != 0.0:
            raise InputError(
                f"wind {meta.wind_ms:g} m/s without a direction: give the direction it comes "
                "from (wind_from_deg), or no wind",
                field="wind_from_deg",
            )
        if meta.wind_from_deg is None:
            return 0.0
        return along_track_wind(meta.wind_ms, meta.wind_from_deg, self.track.azimuth_deg)

    def next_number(self) -> int:
        """The number the next descent to start will get (an open one is already counted)."""
        return self.processor.assembler.count + 1

    def density_for(self, meta: Metadata) -> float:
        """Air density from the descent's metadata where it has P, T, RH; else the config's."""
        air = self.config.air
        if not air.measured and meta.pressure_hpa is None and meta.air_temperature_c is None:
            return air.density
        p = meta.pressure_hpa if meta.pressure_hpa is not None else air.pressure_hpa
        t = meta.air_temperature_c if meta.air_temperature_c is not None else air.temperature_c
        h = meta.humidity_pct if meta.humidity_pct is not None else air.humidity_pct
        if h is None:
            h = 80.0
        if p is None or t is None:
            return self.config.air_density
        return air_density(float(p), float(t), float(h))

    def timer_precision_s(self) -> float:
        """The SD (s) of one crossing time the fits are judged against: the config's
        ``timer.precision_ms``, else from the resolution the timer states in its impulses."""
        if self.config.timer_precision_s is not None:
            return self.config.timer_precision_s
        return precision_from_resolution(self.processor.resolution_us)

    def progress(self) -> Progress:
        cur = self.processor.assembler.current
        nxt = self.next_number()
        if cur is None:
            return Progress(None, (), (), nxt, self.metadata_for(nxt))
        return Progress(
            cur.number, tuple(cur.photocells), tuple(cur.times_us), nxt, self.metadata_for(nxt)
        )

    # -- descents

    def fit_job(self, d: DescentTimes) -> FitJob:
        """What the fit of a descent needs, as things stand now: its start time dated by the
        host time of its start, and the timer's precision as the day judges it."""
        return self.job(
            d,
            start_time(d, self.processor.start_host.get(d.number), self.date),
            self.timer_precision_s(),
        )

    def job(self, d: DescentTimes, started: str, timer_precision_s: float) -> FitJob:
        """What the fit of a descent needs, given its start time and the timer's precision
        (the in-place annotate has them from the results CSV's state, and no processor). The
        item a bib names in the config (``items: {12: {ski: A}}``) is what that descent
        tested."""
        meta = self.metadata_for(d.number)
        item = self.config.items.get(d.bib) if d.bib else None
        if item:
            meta = meta.overlay(Metadata.from_values(item, f"items.{d.bib}."))
        same = self._metas.get(meta)
        if same is None and len(self._metas) < MAX_METADATA:
            self._metas[meta] = meta
        meta = same or meta
        try:
            wind, problem = self.wind_for(meta), ""
        except InputError as exc:  # the descent gets status error with the reason, the day goes on
            wind, problem = 0.0, str(exc)
        return FitJob(
            descent=d,
            start_time=started,
            metadata=meta,
            model=self.models.get(d.number, FitModel(self.config.model)),
            mass_kg=float(meta.mass_kg if meta.mass_kg is not None else self.config.mass_kg),
            air_density=self.density_for(meta),
            wind_ms=wind,
            timer_precision_s=timer_precision_s,
            problem=problem,
        )

    def store(self, res: DescentResult) -> DescentResult:
        """Keep a fit; returns it as the results show it (with its invalid mark)."""
        self.results[res.number] = res
        return self.view(res.number)

    def analyse(self, d: DescentTimes) -> DescentResult:
        """Fit a descent and keep it (the fit runs here: for replays, not for the reader)."""
        return self.store(self.analyser.run(self.fit_job(d)))

    def view(self, number: int) -> DescentResult:
        return self.results[number].marked(self.invalid.get(number, ""))

    def snapshot(self) -> tuple[DescentResult, ...]:
        """Every descent as the results show it, in order: immutable, safe to hand on."""
        return tuple(self.view(k) for k in sorted(self.results))

    # -- annotations

    def annotate(self, a: Annotation) -> Effect:
        """Apply one annotation; says which fits are out of date and which marks changed."""
        self.marks.note(a)
        if isinstance(a, MetadataAnnotation):
            if a.descents is not None:  # already fitted: fit again with the new metadata
                return Effect(refit=tuple(n for n in sorted(set(a.descents)) if n in self.results))
            return Effect()
        n = a.descent
        if isinstance(a, ModelChange):
            return Effect(refit=(n,) if n in self.results else ())
        return Effect(changed=(n,) if n in self.results else ())

    def apply(self, a: Annotation) -> None:
        """Apply an annotation and fit again what it changed, at once (replays)."""
        for n in self.annotate(a).refit:
            self.analyse(self.results[n].descent)
