"""Fits are computed once: each descent's fit stored with its session (``SESSION/fits.jsonl``),
so ``annotate``, ``compare``, ``report``, ``export`` and the UI's replay refit only what changed.

A fit depends on the crossing times, the photocells, the model, the skier's mass, the air, the
wind, g, the survey covariance it was given (computed once per set of photocells, at a
reference fit: :class:`station.session.analysis.Analyser`), the session's config and survey
files and the code that fits. The key of a stored fit is the SHA-256 of all of these (the code
by :func:`station.session.codeversion.code_version`, so a changed station never reads an
older one's fit as its own); an annotation that changes a fit (mass, air, wind, a model) changes its
key, and that fit alone is computed again.

One JSON record a line, appended: ``{"key": …, "fit": {…}}``. The file is a cache, never the
day: a record that cannot be read (torn, from another version, hand-edited into nonsense) is
passed over and that descent fitted again; a session folder that cannot be written (read-only,
a full disk) is replayed with every fit computed, as before. Only a regular file is read, and
at most :data:`MAX_FITS` bytes. When most of the records are no longer used, the file is
rewritten with the used ones only.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import os
import stat
import types
import typing
from collections.abc import Hashable
from functools import cache
from typing import Any

import numpy as np

from station.errors import InputError
from station.files import MAX_OBSERVATIONS, read_bytes, replaced
from station.model.fit import FitResult
from station.session.codeversion import code_version
from station.session.config import StationConfig
from station.session.folder import FITS

#: a stored fit is 2-4 kB: 64 MB holds a season of days
MAX_FITS = 64 * 1024 * 1024


def fit_key(context: str, parts: dict[str, Any], survey_cov: np.ndarray | None) -> str:
    """The key of one fit: what it was computed from (``parts``: JSON values), the survey
    covariance it was handed (its bytes), and ``context`` (files and code)."""
    h = hashlib.sha256(context.encode())
    h.update(json.dumps(parts, sort_keys=True, separators=(",", ":")).encode())
    if survey_cov is not None:
        h.update(np.ascontiguousarray(survey_cov, dtype=float).tobytes())
    return h.hexdigest()


# ----------------------------------------------------------------------------- the JSON form


def to_json(value: Any) -> Any:
    """A fit (or any of its parts) as JSON values; floats keep every bit (repr round-trips)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_json(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, np.ndarray):
        return {"ndarray": value.tolist(), "shape": list(value.shape)}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_json(v) for v in value]
    return value


class _Bad(ValueError):
    """A stored record that is not a fit of this version: passed over."""


Decode = typing.Callable[[Any], Any]


def from_json(kind: Any, value: Any) -> Any:
    """The value of type ``kind`` (a type hint) back from :func:`to_json`'s form; a value that
    does not fit the type raises :class:`_Bad`."""
    return _decoder(kind)(value)


@cache
def _decoder(kind: Any) -> Decode:
    """The decoder of one type, built once: typing's look at the annotations is done here,
    not for every value (it was most of a stored fit's decoding time)."""
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if kind is Any:
        return lambda v: v
    if origin in (typing.Union, types.UnionType):
        return _union([_decoder(a) for a in args if a is not type(None)], type(None) in args)
    if kind is type(None):
        return _null
    if kind is np.ndarray:
        return _array
    if isinstance(kind, type) and dataclasses.is_dataclass(kind):
        return _record(kind)
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        return _member(kind)
    if origin is list:
        item = _decoder(args[0] if args else Any)
        return lambda v: [item(x) for x in _of(v, list)]
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            each = _decoder(args[0])
            return lambda v: tuple(each(x) for x in _of(v, list))
        items = [_decoder(a) for a in args]
        return lambda v: _fixed_tuple(items, _of(v, list))
    if origin is dict:
        val = _decoder(args[1] if args else Any)
        return lambda v: {_of(k, str): val(x) for k, x in _of(v, dict).items()}
    if kind is float:
        return _float
    if kind is int:
        return _int
    if kind in (str, bool):
        return lambda v: _of(v, kind)
    raise _Bad(f"no JSON form for {kind!r}")


def _of(value: Any, kind: type) -> Any:
    if not isinstance(value, kind):
        raise _Bad(f"expected {kind.__name__}")
    return value


def _null(value: Any) -> None:
    if value is not None:
        raise _Bad("expected null")


def _float(value: Any) -> float:
    if type(value) is float:
        return value
    if isinstance(value, bool) or not isinstance(value, int):
        raise _Bad("expected a number")
    return float(value)


def _int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _Bad("expected a whole number")
    return value


def _union(options: list[Decode], nullable: bool) -> Decode:
    def decode(value: Any) -> Any:
        if value is None and nullable:
            return None
        for option in options:
            try:
                return option(value)
            except _Bad:
                continue
        raise _Bad(f"{value!r} is of none of the types expected")

    return decode


def _array(value: Any) -> np.ndarray:
    if not isinstance(value, dict) or "ndarray" not in value:
        raise _Bad("expected an array")
    a = np.array(value["ndarray"], dtype=float)
    if list(a.shape) != value.get("shape"):
        raise _Bad("array of the wrong shape")
    return a


def _fixed_tuple(items: list[Decode], value: list) -> tuple:
    if len(items) != len(value):
        raise _Bad("a tuple of the wrong length")
    if len(items) == 2:  # an interval: most tuples of a fit (a generator costs 3× as much)
        return (items[0](value[0]), items[1](value[1]))
    return tuple([d(x) for d, x in zip(items, value, strict=True)])


def _member(kind: type[enum.Enum]) -> Decode:
    def decode(value: Any) -> Any:
        try:
            return kind(value)
        except ValueError:
            raise _Bad(f"{value!r} is no {kind.__name__}") from None

    return decode


def _record(kind: type) -> Decode:
    hints = typing.get_type_hints(kind)
    names = frozenset(f.name for f in dataclasses.fields(kind) if f.init)
    fields = {name: _decoder(hints[name]) for name in names}

    def decode(value: Any) -> Any:
        if not isinstance(value, dict) or value.keys() != names:
            raise _Bad(f"not a {kind.__name__} of this version")
        return kind(**{k: d(value[k]) for k, d in fields.items()})

    return decode


def fit_from_json(value: Any) -> FitResult:
    fit = from_json(FitResult, value)
    if not isinstance(fit, FitResult):  # pragma: no cover - from_json builds the kind asked
        raise _Bad("not a fit")
    return fit


# ----------------------------------------------------------------------------- the store


def session_context(config: StationConfig) -> str:
    """The files and code every fit of a session depends on, as one string."""
    digests = [
        hashlib.sha256(read_bytes(p, MAX_OBSERVATIONS, what)).hexdigest()
        for p, what in ((config.path, "config"), (config.survey_path, "survey file"))
    ]
    return "|".join([*digests, code_version()])


#: a key as the store holds it in memory (:func:`_held`)
Held = bytes | str


def _held(key: str) -> Held:
    """A key as the store holds it: a SHA-256 in hex (what :func:`fit_key` makes) as its 32
    bytes, 65 bytes of memory, not the hex string's 113 (a day holds 2000); any other string
    as it is."""
    if len(key) == 64:
        try:
            digest = bytes.fromhex(key)
        except ValueError:
            return key
        if digest.hex() == key:
            return digest
    return key


def _key(held: Held) -> str:
    return held if isinstance(held, str) else held.hex()


#: the longest line a stored fit takes (a fit of 64 photocells is some 25 kB)
MAX_LINE = 1 << 20


class FitStore:
    """The stored fits of one session: read when opened, a new fit appended as it is made.
    What the analyser asks for (:class:`station.session.analysis.FitCache`).

    In memory it keeps where each fit's line starts in the file, not the fit: a recording of
    2000 descents kept every fit's JSON form as Python objects, 6.6 kB a descent (issue 18's
    memory target is 2 kB). A fit asked for again is read back from its line (0.5 ms), and a
    line that is not the fit's any more (another process compacted the file) is a miss: the
    fit is computed again, never taken from the wrong line."""

    def __init__(self, path: str, context: str) -> None:
        self.path = path
        self.context = context
        #: fits that could not be written (a read-only copy, a full disk): their JSON form
        self._fits: dict[str, Any] = {}
        #: fits in the file, by the key as held (:func:`_held`): the offset of their line,
        #: or ``~offset`` (negative) for a fit not asked for since the file was opened
        self._where: dict[Held, int] = {}
        self._records = 0
        self._put: Held | None = None  # the key of the fit written last
        self.hits = 0
        self.misses = 0
        self._writable = True
        self._read()

    @classmethod
    def for_session(cls, session: str, config: StationConfig) -> FitStore | None:
        """The store of a session; None when its config or survey cannot be read for the key
        (the replay then says why, as before)."""
        try:
            context = session_context(config)
        except InputError:
            return None
        return cls(os.path.join(session, FITS), context)

    def _read(self) -> None:
        if not os.path.lexists(self.path):
            return
        try:
            data = read_bytes(self.path, MAX_FITS, "stored fits")
        except InputError:
            self._writable = False  # not a regular file, or too large: leave it alone
            return
        offset = 0
        for line in data.split(b"\n"):
            at, offset = offset, offset + len(line) + 1
            if not line.strip():
                continue
            self._records += 1
            try:
                rec = json.loads(line)
            except ValueError:
                continue
            if isinstance(rec, dict) and isinstance(rec.get("key"), str) and "fit" in rec:
                self._where[_held(rec["key"])] = ~at  # not used yet

    def _load(self, key: str) -> Any:
        """The JSON form of a fit from its line in the file; None when that line is not the
        fit's any more (the file was compacted or cut since) or cannot be read."""
        at = self._where.get(_held(key))
        if at is not None and at < 0:
            at = ~at
        if at is None:
            return None
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO put there: no wait
            with os.fdopen(fd, "rb") as fh:
                if not stat.S_ISREG(os.fstat(fd).st_mode):
                    return None
                fh.seek(at)
                line = fh.readline(MAX_LINE)
            rec = json.loads(line)
        except (OSError, ValueError):
            return None
        if not isinstance(rec, dict) or rec.get("key") != key or "fit" not in rec:
            return None
        return rec["fit"]

    def key(self, parts: dict[str, Any], survey_cov: np.ndarray | None) -> str:
        return fit_key(self.context, parts, survey_cov)

    def handle(self, key: str) -> Held | None:
        """Where the fit is kept when it is in the file (:meth:`get` takes it for the key),
        None when it is not (only in memory, or not stored): the key as the store holds it,
        the very object, so that one who keeps it keeps no copy."""
        held = _held(key)
        if held == self._put and held in self._where:  # just written (a recording's every fit)
            return self._put
        at = self._where.pop(held, None)
        if at is None:
            return None
        self._where[held] = at  # the index now holds this very object
        return held

    def _forget(self, key: str) -> None:
        self._where.pop(_held(key), None)

    def get(self, key: Hashable) -> FitResult | None:
        """The fit of a key, or of what :meth:`handle` gave; None when the store has none."""
        key = key.hex() if isinstance(key, bytes) else str(key)
        stored = self._fits.get(key)
        if stored is None:
            stored = self._load(key)
        if stored is None:
            self._forget(key)
            self.misses += 1
            return None
        try:
            fit = fit_from_json(stored)
        except (_Bad, TypeError, ValueError, OverflowError):
            self._fits.pop(key, None)
            self._forget(key)
            self.misses += 1
            return None
        held = _held(key)
        at = self._where.get(held)
        if at is not None and at < 0:
            self._where[held] = ~at  # used
        self.hits += 1
        return fit

    def put(self, key: str, fit: FitResult) -> None:
        form = to_json(fit)
        held = _held(key)
        if not self._writable:
            self._fits[key] = form
            return
        data = (json.dumps({"key": key, "fit": form}, separators=(",", ":")) + "\n").encode()
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK, 0o644)
            try:
                written = os.write(fd, data)  # one write: a concurrent writer's lines stay whole
                end = os.lseek(fd, 0, os.SEEK_CUR)
            finally:
                os.close(fd)
            self._records += 1
        except OSError:
            self._writable = False  # a read-only copy, a full disk: fits are computed, not kept
            self._fits[key] = form
            return
        if written == len(data):
            self._where[held] = end - len(data)
            self._put = held
            self._fits.pop(key, None)
        else:  # a short write: the line is torn; keep the fit here
            self._fits[key] = form

    @property
    def used(self) -> set[str]:
        """The keys of the fits asked for or made since the store was opened."""
        made = {_key(h) for h, at in self._where.items() if at >= 0}
        return made | self._fits.keys()

    def compact(self) -> None:
        """Rewrite the file with the fits used since it was opened, when most records are not
        (every annotation leaves the fits it replaced behind)."""
        used = self.used
        if not self._writable or self._records <= 2 * len(used) + 100:
            return
        try:
            with replaced(self.path) as tmp, open(tmp, "wb") as fh:
                where: dict[Held, int] = {}
                for key in sorted(used):
                    form = self._fits.get(key)
                    if form is None:
                        form = self._load(key)
                    if form is not None:
                        where[_held(key)] = fh.tell()
                        line = json.dumps({"key": key, "fit": form}, separators=(",", ":"))
                        fh.write(line.encode() + b"\n")
            self._records = len(used)
            self._where = where
            for held in where:
                self._fits.pop(_key(held), None)
        except OSError:
            pass  # the old file stays: a cache
