"""The engineer's annotations of a day as they stand, without the day's fits: the metadata in
force for each descent, the invalid marks and the models asked for.

One set of rules for two users: :class:`station.session.day.Day`, which fits, and the in-place
annotate (:mod:`station.session.resultsstate`), which rewrites rows of the results CSV without
importing the fit (0.9 s of numpy and scipy). Written twice, the two could tell a descent's
metadata apart, and the in-place CSV would no longer be the replay's. Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from station.session.config import StationConfig
from station.session.records import (
    Annotation,
    FitModel,
    InvalidMark,
    Metadata,
    MetadataAnnotation,
    ModelChange,
    ValidMark,
)

__all__ = ["Marks", "config_metadata"]


def config_metadata(config: StationConfig) -> Metadata:
    """The metadata the config gives every descent: the skier's mass, its ``metadata:`` block
    and the air it measured."""
    values: dict[str, object] = {"mass_kg": config.mass_kg, **config.metadata}
    air = config.air
    if air.measured:
        values["pressure_hpa"] = air.pressure_hpa
        values["air_temperature_c"] = air.temperature_c
        values["humidity_pct"] = air.humidity_pct
    return Metadata.from_values(values)


@dataclass
class Marks:
    """What the annotations said so far, in the order they were made."""

    base: Metadata  # the config's (config_metadata)
    #: metadata changes ``from`` a descent number on
    changes: list[tuple[int, Metadata]] = field(default_factory=list)
    #: metadata for listed descents only (the most specific)
    listed: list[tuple[frozenset[int], Metadata]] = field(default_factory=list)
    invalid: dict[int, str] = field(default_factory=dict)  # descent → reason
    models: dict[int, FitModel] = field(default_factory=dict)  # descent → model asked for
    #: ``base`` with every change "from N on" made so far overlaid, in order: (how many
    #: changes, the last one, the result, their largest N). Metadata entered before each
    #: descent made ``metadata_for`` overlay the whole day's changes on every impulse (34 ms a
    #: call at descent 440, on the reader's thread: benchmarks/ui_fit_latency.py); now only
    #: the changes made since its last call
    _folded: tuple[int, object, Metadata | None, int] = field(
        default=(0, None, None, 0), repr=False, compare=False
    )

    @classmethod
    def of(cls, config: StationConfig, annotations: Iterable[Annotation] = ()) -> Marks:
        marks = cls(config_metadata(config))
        for a in annotations:
            marks.note(a)
        return marks

    def note(self, a: Annotation) -> None:
        """Take one annotation in (what it changes in the fits is the day's to say)."""
        if isinstance(a, MetadataAnnotation):
            if a.descents is not None:
                self.listed.append((frozenset(a.descents), a.values))
            else:
                self.changes.append((a.from_descent or 0, a.values))
        elif isinstance(a, InvalidMark):
            self.invalid[a.descent] = a.reason or "marked invalid"
        elif isinstance(a, ValidMark):
            self.invalid.pop(a.descent, None)
        elif isinstance(a, ModelChange):
            self.models[a.descent] = a.model

    def metadata_for(self, number: int) -> Metadata:
        """Metadata in force for a descent: the config's, then the changes ``from`` a number on
        in the order they were made, then those for listed descents only (the most specific)."""
        changes = self.changes
        done, last, folded, latest = self._folded
        if folded is None or done > len(changes) or (done and changes[done - 1] is not last):
            done, folded, latest = 0, self.base, 0  # first call, or the list was changed
        if done < len(changes):
            for start, values in changes[done:]:
                folded = folded.overlay(values)
                latest = max(latest, start)
            done = len(changes)
            self._folded = (done, changes[-1], folded, latest)
        if number >= latest:  # every change applies (the usual case: the later descents)
            meta = folded
        else:
            meta = self.base
            for start, values in changes:
                if start <= number:
                    meta = meta.overlay(values)
        for descents, values in self.listed:
            if number in descents:
                meta = meta.overlay(values)
        return meta
