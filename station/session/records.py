"""The typed records of a test day: statuses, fit models, run metadata, annotations, the
finished descent as fitted, and the row of the results CSV.

They are frozen, so one can be handed from the fit worker to the UI thread without a lock: a
change is a new record, never an edit of one someone else holds. The results CSV and
``annotations.jsonl`` are views of them, each written by one function here
(:func:`csv_record`, :func:`annotation_to_json`) and the annotations read back by one
(:func:`annotation_from_json`). Pure: no I/O, no threads.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from station.errors import InputError
from station.model.estimate import FitStatus

if TYPE_CHECKING:  # for annotations only: `station fit` need not load the assembler
    from station.timing.assembly import TimedDescent


class ResultStatus(StrEnum):
    """The status column of the results: the fit's verdict (:class:`station.model.estimate.
    FitStatus`, each of which is one of these), or why there is no fit. The values are the
    strings earlier versions wrote, so existing results files read the same."""

    OK = "ok"
    ILL_CONDITIONED = "ill-conditioned"
    LIFT_OFF = "lift-off"
    STOPPED = "stopped"
    TOO_FEW_PHOTOCELLS = "too-few-photocells"
    NOT_CONVERGED = "not-converged"
    POOR_FIT = "poor-fit"  # residuals far above the timer's precision (χ² test)
    ABORTED = "aborted"  # a lone start impulse: nothing to fit
    ERROR = "error"  # the fit raised: the reason is in the flags
    INVALID = "invalid"  # the results CSV's word for a descent marked invalid (invalid_reason)


class DescentStatus(StrEnum):
    """How a descent ended: at the last photocell, short of it, or a lone start impulse."""

    OPEN = "open"
    COMPLETE = "complete"
    INCOMPLETE = "incomplete"
    ABORTED = "aborted"


class FitModel(StrEnum):
    """Constant friction μ, or μ + μ1·v."""

    CONSTANT = "constant"
    VELOCITY = "velocity"


#: the name earlier code used: the status column of the results
Status = ResultStatus


def fit_status(status: FitStatus | str) -> tuple[ResultStatus, str]:
    """The fit's status as the results' :class:`ResultStatus`; a string this version does not
    know is an error with a reason, never passed over."""
    try:
        return ResultStatus(str(status)), ""
    except ValueError:
        return ResultStatus.ERROR, f"unknown fit status {status!r}"


# ----------------------------------------------------------------------------- metadata


@dataclass(frozen=True)
class MetadataField:
    """One key of the run metadata: its type, unit and label, the ``station annotate`` option,
    the check of its value (a name the CLI maps to its number parser) and whether it is a
    column of the results CSV as entered (mass and wind enter the fit and have columns of their
    own: the mass used and the wind along the track)."""

    key: str
    kind: type
    label: str
    unit: str = ""
    option: str = ""
    check: str = "text"  # text | number | positive | nonnegative | percent | celsius
    column: bool = True
    help: str | None = None
    choices: tuple[str, ...] = ()  # the values a class takes (snow type, wetness, hardness)

    @property
    def title(self) -> str:
        return f"{self.label} [{self.unit}]" if self.unit else self.label


def _meta(label: str, kind: type = float, unit: str = "", **kw: Any) -> Any:
    return field(default=None, metadata={"spec": (kind, label, unit, kw)})


#: the snow as testers record it: the grain-shape classes of the international classification
#: for seasonal snow on the ground (Fierz et al. 2009): PP new snow (precipitation particles),
#: MM machine-made, DF decomposing fragments, RG rounded grains, FC faceted crystals, DH depth
#: hoar, SH surface hoar, MF melt forms, IF ice formations
SNOW_TYPES = ("PP", "MM", "DF", "RG", "FC", "DH", "SH", "MF", "IF")
#: liquid water content: dry 0 %, moist < 3 %, wet 3–8 %, very wet 8–15 %, soaked > 15 %
WETNESS = ("dry", "moist", "wet", "very wet", "soaked")
#: hand hardness: fist, four fingers, one finger, pencil, knife blade, ice
HARDNESS = ("F", "4F", "1F", "P", "K", "I")
_WETNESS_CODES = dict(zip("DMWVS", WETNESS, strict=True))


def choice(value: str, choices: tuple[str, ...], key: str) -> str:
    """A class as the table spells it, whatever the case (``mf`` is MF, ``very-wet`` and the
    classification's letter ``V`` are "very wet"); anything else is an :class:`InputError`."""
    text = " ".join(str(value).replace("-", " ").replace("_", " ").split())
    for c in choices:
        if text.casefold() == c.casefold():
            return c
    if choices == WETNESS and text.upper() in _WETNESS_CODES:
        return _WETNESS_CODES[text.upper()]
    raise InputError(f"{value!r} is not one of {', '.join(choices)}", field=key)


@dataclass(frozen=True)
class Metadata:
    """What the engineer says about the descents that follow: the one declaration of the keys.

    ``None`` is "not given": a change of metadata names only the keys it changes, and the
    values in force for a descent are the config's overlaid by the changes in order.
    """

    skier: str | None = _meta("skier", str)
    mass_kg: float | None = _meta(
        "mass incl. equipment", unit="kg", option="--mass", check="positive", column=False
    )
    ski: str | None = _meta("ski / pair id", str, help="ski or pair id")
    # the item beside ski and wax: kept in the annotations and the season store; results.csv
    # keeps the columns it always had (column=False), so its bytes do not change
    grind: str | None = _meta("grind / structure", str, column=False)
    base: str | None = _meta("base", str, column=False, help="base material or model")
    wax: str | None = _meta("wax", str)
    air_temperature_c: float | None = _meta("air temperature", unit="°C", check="celsius")
    snow_temperature_c: float | None = _meta("snow temperature", unit="°C", check="celsius")
    snow_type: str | None = _meta(
        "snow type",
        str,
        column=False,
        choices=SNOW_TYPES,
        help="grain shape: PP new, MM machine-made, DF, RG, FC, DH, SH, MF melt forms, IF",
    )
    grain_size_mm: float | None = _meta(
        "grain size", unit="mm", check="positive", column=False, help="grain size (mm)"
    )
    wetness: str | None = _meta(
        "wetness", str, column=False, choices=WETNESS, help="dry, moist, wet, very wet, soaked"
    )
    hardness: str | None = _meta(
        "hand hardness", str, column=False, choices=HARDNESS, help="hand hardness: F 4F 1F P K I"
    )
    pressure_hpa: float | None = _meta("station pressure", unit="hPa", check="positive")
    humidity_pct: float | None = _meta("relative humidity", unit="%", check="percent")
    wind_ms: float | None = _meta(
        "wind speed", unit="m/s", check="nonnegative", column=False, help="wind speed"
    )
    wind_from_deg: float | None = _meta(
        "wind from",
        unit="° from north",
        check="number",
        column=False,
        help="direction the wind comes from",
    )
    notes: str | None = _meta("notes", str)

    @classmethod
    def from_values(cls, values: Mapping[str, Any], where: str = "") -> Metadata:
        """Typed metadata from a mapping of keys to values (a form, a JSON record); keys that
        are not metadata are passed over, as earlier versions did."""
        out: dict[str, Any] = {}
        for f in METADATA_FIELDS:
            v = values.get(f.key)
            if v is None:
                continue
            if f.kind is float:
                try:
                    number = float(v)
                except (TypeError, ValueError):
                    raise InputError(f"{v!r} is not a number", field=where + f.key) from None
                if not math.isfinite(number) or isinstance(v, bool):
                    raise InputError(f"{v!r} is not a finite number", field=where + f.key)
                out[f.key] = number
            elif f.choices:
                out[f.key] = choice(str(v), f.choices, where + f.key)
            else:
                out[f.key] = str(v)
        return cls(**out)

    def values(self) -> dict[str, Any]:
        """The keys that are given, in the order of the declaration."""
        out = {f.key: getattr(self, f.key) for f in METADATA_FIELDS}
        return {k: v for k, v in out.items() if v is not None}

    def overlay(self, other: Metadata) -> Metadata:
        """These values, with those ``other`` gives in their place."""
        return dataclasses.replace(self, **other.values())


def _fields() -> tuple[MetadataField, ...]:
    out = []
    for f in fields(Metadata):
        kind, label, unit, spec = f.metadata["spec"]
        kw = dict(spec)
        option = kw.pop("option", "--" + f.name.replace("_", "-"))
        out.append(MetadataField(f.name, kind, label, unit, option, **kw))
    return tuple(out)


#: the metadata keys in the order the form shows them: the one table the UI form, ``station
#: annotate``, the results CSV and the day read
METADATA_FIELDS: tuple[MetadataField, ...] = _fields()


# ----------------------------------------------------------------------------- annotations


@dataclass(frozen=True)
class MetadataAnnotation:
    """Metadata for the descents from ``from_descent`` on, or for the listed ``descents``."""

    values: Metadata
    from_descent: int | None = None
    descents: tuple[int, ...] | None = None
    t: float | None = None


@dataclass(frozen=True)
class InvalidMark:
    descent: int
    reason: str = "marked invalid"
    t: float | None = None


@dataclass(frozen=True)
class ValidMark:
    descent: int
    t: float | None = None


@dataclass(frozen=True)
class ModelChange:
    descent: int
    model: FitModel
    t: float | None = None


Annotation = MetadataAnnotation | InvalidMark | ValidMark | ModelChange


def annotation_to_json(a: Annotation) -> dict[str, Any]:
    """The record of ``annotations.jsonl`` (the format earlier versions wrote)."""
    rec: dict[str, Any] = {} if a.t is None else {"t": a.t}
    if isinstance(a, MetadataAnnotation):
        rec |= {"type": "metadata", "values": a.values.values()}
        if a.descents is not None:
            rec["descents"] = list(a.descents)
        else:
            rec["from"] = a.from_descent
    elif isinstance(a, InvalidMark):
        rec |= {"type": "invalid", "descent": a.descent, "reason": a.reason}
    elif isinstance(a, ValidMark):
        rec |= {"type": "valid", "descent": a.descent}
    else:
        rec |= {"type": "model", "descent": a.descent, "model": a.model.value}
    return rec


def annotation_from_json(rec: Mapping[str, Any]) -> Annotation | None:
    """One record of ``annotations.jsonl``; ``None`` for a kind this version does not know.
    A bad value raises :class:`InputError` naming the field (the caller adds file and line)."""

    def number(key: str) -> int:
        return _descent_number(rec.get(key), key)

    t = rec.get("t")
    t = float(t) if isinstance(t, (int, float)) and not isinstance(t, bool) else None
    kind = rec.get("type")
    if kind == "metadata":
        values = rec.get("values", {})
        if not isinstance(values, Mapping):
            raise InputError("expected a mapping of metadata", field="values")
        meta = Metadata.from_values(values, "values.")
        _plausible(meta)
        if "descents" in rec:
            key = "descents"
            ds = rec[key]
            if not isinstance(ds, list):
                raise InputError(f"expected a list of descent numbers, got {ds!r}", field=key)
            nums = tuple(_descent_number(x, "descents") for x in ds)
            return MetadataAnnotation(meta, descents=nums, t=t)
        return MetadataAnnotation(meta, from_descent=number("from"), t=t)
    if kind == "invalid":
        return InvalidMark(number("descent"), str(rec.get("reason", "")) or "marked invalid", t)
    if kind == "valid":
        return ValidMark(number("descent"), t)
    if kind == "model":
        try:
            model = FitModel(str(rec.get("model", "constant")))
        except ValueError:
            raise InputError(f"unknown model {rec.get('model')!r}", field="model") from None
        return ModelChange(number("descent"), model, t)
    return None


def _plausible(meta: Metadata) -> None:
    """A number read back from a file is in the range the form and the command line let in
    (station/limits.py): ``mass_kg: 1e308`` in an edited annotations file is refused naming
    the field, not fitted as ``ill-conditioned``."""
    from station.limits import PLAUSIBLE

    for key, value in meta.values().items():
        if key in PLAUSIBLE and isinstance(value, float):
            lo, hi, unit = PLAUSIBLE[key]
            if not lo <= value <= hi:
                raise InputError(f"{value:g} is outside {lo:g} to {hi:g} {unit}",
                                 field="values." + key)  # fmt: skip


def _descent_number(v: Any, key: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        raise InputError(f"expected a descent number, got {v!r}", field=key)
    try:
        number = int(v)
    except (ValueError, OverflowError):
        raise InputError(f"expected a descent number, got {v!r}", field=key) from None
    if number != v and not isinstance(v, str) or not 1 <= number <= MAX_DESCENT:
        # 1.5 is no descent, and 1e300 none of a day's (it was taken as a 301-digit number)
        raise InputError(f"expected a descent number (1 to {MAX_DESCENT}), got {v!r}", field=key)
    return number


#: the highest descent number an annotation may name: far beyond any test day
MAX_DESCENT = 1_000_000


# ----------------------------------------------------------------------------- descents


#: tuples that most descents of a day have alike (the photocells, the channels): one object
#: for them all, not one each (a 2000-descent day's results are kept in memory); bounded
_SHARED: dict[tuple[str, ...], tuple[str, ...]] = {}
_MAX_SHARED = 4096


def shared(items: list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """``items`` as a tuple, the same object as an equal one made before."""
    t = tuple(items)
    same = _SHARED.get(t)
    if same is not None:
        return same
    if len(_SHARED) < _MAX_SHARED:
        _SHARED[t] = t
    return t


@dataclass(frozen=True, slots=True)
class DescentTimes:
    """A finished descent as the fit and the results see it: a frozen copy of the assembler's
    :class:`TimedDescent`, so nothing the UI holds can change under it. Kept for every descent
    of the day: slots, and the photocells and channels shared among descents."""

    number: int
    photocells: tuple[str, ...]
    times_us: tuple[int, ...]
    status: DescentStatus
    flags: tuple[str, ...] = ()
    missing: tuple[str, ...] = ()
    bib: str = ""  # the start's bib, where the timer sends bibs (not a counter)
    channels: tuple[str, ...] = ()  # the timer channel of each time
    day: int | None = None  # days since 2000-01-01 of the start, where the device says (TAG)
    first_us: int | None = None  # the first time it had (its times may all have been cleared)

    @classmethod
    def of(cls, d: TimedDescent) -> DescentTimes:
        return cls(
            d.number,
            shared(d.photocells),
            tuple(d.times_us),
            DescentStatus(d.status),
            tuple(d.flags),
            shared(d.missing),
            d.bib,
            shared(d.channels),
            d.day,
            d.first_us,
        )

    @property
    def start_us(self) -> int:
        return self.times_us[0] if self.times_us else (self.first_us or 0)


@dataclass(frozen=True)
class LineCounts:
    """What the timer sent so far, by kind of line."""

    lines: int = 0
    impulses: int = 0
    edits: int = 0
    skipped: int = 0
    unparsed: int = 0
    #: of the impulses, those from the timer's memory (an ALGE ``m`` line, a TAG download's)
    from_memory: int = 0


@dataclass(frozen=True)
class Progress:
    """The open descent (``number`` None: none open), and what the next descent will get: its
    number and the metadata in force for it (what the metadata form starts from)."""

    number: int | None
    passed: tuple[str, ...]
    times_us: tuple[int, ...]
    next_number: int
    next_metadata: Metadata


# ----------------------------------------------------------------------------- results row


@dataclass(frozen=True, slots=True)
class ResultRow:
    """One descent in the results: the row of the results CSV, read by attribute (kept for
    every descent of the day: slots)."""

    descent: int
    start_time: str
    photocells_used: int
    missing: tuple[str, ...]
    v0: float | None
    cda: float | None
    cda_lo: float | None
    cda_hi: float | None
    mu: float | None
    mu_lo: float | None
    mu_hi: float | None
    mu1: float | None
    sigma_s2: float | None
    rms_residual_ms: float | None
    status: ResultStatus
    descent_status: DescentStatus
    flags: tuple[str, ...]
    model: FitModel
    mass_kg: float
    air_density: float
    wind_ms: float
    metadata: Metadata
    gravity: float = 9.80665  # m/s² the fit used (the site's, from the survey's latitude)
    invalid_reason: str = ""

    @property
    def skier(self) -> str:
        return self.metadata.skier or ""

    @property
    def ski(self) -> str:
        return self.metadata.ski or ""

    @property
    def wax(self) -> str:
        return self.metadata.wax or ""

    @property
    def notes(self) -> str:
        return self.metadata.notes or ""

    @property
    def invalid(self) -> bool:
        return bool(self.invalid_reason)


#: where the metadata columns go among the others (the order of earlier versions' files)
_BEFORE_META = (
    "descent", "start_time", "photocells_used", "missing", "v0", "cda", "cda_lo", "cda_hi",
    "mu", "mu_lo", "mu_hi", "mu1", "sigma_s2", "rms_residual_ms", "status", "descent_status",
    "flags", "model", "mass_kg", "air_density", "gravity", "wind_ms",
)  # fmt: skip


def csv_record(row: ResultRow) -> dict[str, Any]:
    """The row as the results CSV writes it: text joined, enums as their strings, metadata
    columns from the one table (text "" and numbers None when not given)."""
    out: dict[str, Any] = {}
    for key in _BEFORE_META:
        v = getattr(row, key)
        if key in ("missing", "flags"):
            v = (" " if key == "missing" else "; ").join(v)
        elif isinstance(v, StrEnum):
            v = v.value
        if key == "status" and row.invalid_reason:
            # a descent marked invalid does not read "ok" to whoever filters on the status;
            # its fit stays in the other columns, the reason in invalid_reason
            v = ResultStatus.INVALID.value
        out[key] = v
    for f in METADATA_FIELDS:
        if f.column:
            v = getattr(row.metadata, f.key)
            out[f.key] = ("" if v is None else v) if f.kind is str else v
    out["invalid_reason"] = row.invalid_reason
    return out
