"""YAML loading that remembers line numbers, so a bad key or value is reported where it stands.

``yaml.safe_load`` forgets where things came from. Here mappings load as :class:`LineDict` and
sequences as :class:`LineList`, each knowing the 1-based line of every key or item; the
:class:`Section` helper checks keys and types and raises :class:`InputError` naming file, line
and field.

A YAML file is input like any other and is bounded like one: at most ``MAX_DEPTH`` levels of
nesting (20 000 levels overflowed Python's stack), at most ``MAX_NODES`` values once aliases are
expanded (a "billion laughs" bomb of nine nested aliases expands to 10⁹ values and ran past 20 s
and 1.4 GB), and a bounded file size (:mod:`station.files`). Numbers must be finite: ``.nan``
and ``.inf`` are refused wherever a number is read.
"""

from __future__ import annotations

import math
from typing import Any

import yaml

from station.errors import InputError
from station.files import MAX_YAML, read_text
from station.numbers import parse_number

MAX_DEPTH = 64
MAX_NODES = 200_000


class LineDict(dict):
    """A dict that also knows the line of each key (``lines``) and of itself (``line``)."""

    line: int = 0

    def __init__(self) -> None:
        super().__init__()
        self.lines: dict[Any, int] = {}


class LineList(list):
    """A list that also knows the line of each item (``lines``) and of itself (``line``)."""

    line: int = 0

    def __init__(self) -> None:
        super().__init__()
        self.lines: list[int] = []


class _Limit(yaml.YAMLError):
    """Nesting or alias expansion over the limits; carries where it was found."""

    def __init__(self, problem: str, mark: Any) -> None:
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = mark


class _Loader(yaml.SafeLoader):
    """SafeLoader with bounded nesting (checked while composing, before Python's stack is at
    risk) and bounded alias expansion (checked on the composed graph, before constructing)."""

    _depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise _Limit(f"nested deeper than {MAX_DEPTH} levels", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_data(self) -> Any:
        node = self.get_single_node()
        if node is None:
            return None
        _check_expansion(node)
        return self.construct_document(node)


def _check_expansion(root: yaml.Node) -> None:
    """Count the values the document expands to, each alias counted as a copy (memoised, so
    the count itself is linear in the file); refuse a recursive alias."""
    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in active:
            raise _Limit("an alias refers to itself", node.start_mark)
        active.add(key)
        n = 1
        if isinstance(node, yaml.SequenceNode):
            n += sum(size(item) for item in node.value)
        elif isinstance(node, yaml.MappingNode):
            n += sum(size(k) + size(v) for k, v in node.value)
        active.discard(key)
        if n > MAX_NODES:
            raise _Limit(
                f"expands to more than {MAX_NODES} values (aliases repeated within aliases?)",
                node.start_mark,
            )
        sizes[key] = n
        return n

    size(root)


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    out = LineDict()
    out.line = node.start_mark.line + 1
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None,
                None,
                "a key must be a plain value, not a list or mapping",
                key_node.start_mark,
            ) from None
        out[key] = loader.construct_object(value_node, deep=True)
        out.lines[key] = key_node.start_mark.line + 1
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LineList:
    out = LineList()
    out.line = node.start_mark.line + 1
    for item in node.value:
        out.append(loader.construct_object(item, deep=True))
        out.lines.append(item.start_mark.line + 1)
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_yaml(path: str, what: str = "YAML file") -> Any:
    """Load a YAML file with line numbers; unreadable, special, oversized or malformed files
    raise InputError."""
    return parse_yaml(read_yaml_text(path, what), path)


def read_yaml_text(path: str, what: str = "YAML file") -> str:
    """The text of a YAML file: a regular file of at most ``MAX_YAML`` bytes, in UTF-8."""
    return read_text(path, MAX_YAML, what)


def parse_yaml(text: str, path: str) -> Any:
    """YAML text (read from ``path``) with line numbers, within the limits of this module."""
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"not valid YAML: {problem}", path=path, line=line) from None
    except (ValueError, OverflowError) as exc:
        # e.g. an integer of 5 000 digits (Python refuses to convert it)
        reason = str(exc).splitlines()[0][:80] if str(exc) else type(exc).__name__
        if "integer string conversion" in reason:
            reason = "a number with thousands of digits"
        raise InputError(f"not valid YAML: {reason}", path=path) from None
    except RecursionError:
        raise InputError("not valid YAML: nested too deep", path=path) from None


_TYPE_NAMES = {float: "a number", int: "a whole number", str: "text", bool: "true or false"}


class Section:
    """A checked view of one YAML mapping: known keys only, typed access, located errors."""

    def __init__(self, data: Any, path: str, name: str, allowed: set[str], line: int = 0):
        self.path = path
        self.name = name
        if data is None:
            data = LineDict()
        if not isinstance(data, dict):
            raise InputError(
                "expected a mapping of keys to values",
                path=path,
                line=getattr(data, "line", None) or line or None,
                field=name or "(top level)",
            )
        self.data = data
        for key in data:
            if key not in allowed:
                known = ", ".join(sorted(allowed))
                hint = ""
                if isinstance(key, int) or (isinstance(key, str) and key.isdigit()):
                    # {mass_kg: 72,5} reads as mass_kg: 72 and a key "5"
                    hint = "; a decimal comma inside { } splits a number: write 72.5 or '72,5'"
                raise InputError(
                    f"unknown key (known keys: {known}){hint}",
                    path=path,
                    line=self.line_of(key),
                    field=self.field(key),
                )

    def field(self, key: str) -> str:
        return f"{self.name}.{key}" if self.name else str(key)

    def line_of(self, key: str) -> int | None:
        lines = getattr(self.data, "lines", {})
        return lines.get(key) or getattr(self.data, "line", None) or None

    def has(self, key: str) -> bool:
        return key in self.data and self.data[key] is not None

    def error(self, key: str, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.line_of(key), field=self.field(key))

    def get(self, key: str, kind: type, default: Any = None, *, required: bool = False) -> Any:
        """The value of ``key`` as ``kind`` (int accepted for float), or ``default``."""
        if key not in self.data or self.data[key] is None:
            if required:
                raise InputError(
                    "missing required key",
                    path=self.path,
                    line=getattr(self.data, "line", None) or None,
                    field=self.field(key),
                )
            return default
        value = self.data[key]
        if kind is float and not isinstance(value, bool):
            return self._float(key, value)
        if kind is str and isinstance(value, (int, float)) and not isinstance(value, bool):
            return str(value)
        if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
            raise self.error(
                key, f"expected {_TYPE_NAMES.get(kind, kind.__name__)}, got {show(value)}"
            )
        return value

    def _float(self, key: str, value: Any) -> float:
        """A finite float from a YAML number or from text such as ``72,5`` or ``1e-3`` (which
        YAML 1.1 leaves as text)."""
        if isinstance(value, str):
            try:
                return parse_number(value)
            except ValueError as exc:
                raise self.error(key, f"expected a number: {exc}") from None
        if isinstance(value, int):
            try:
                value = float(value)
            except OverflowError:
                raise self.error(key, f"the number {show(value)} is too large") from None
        if not isinstance(value, float):
            raise self.error(key, f"expected a number, got {show(value)}")
        if not math.isfinite(value):
            raise self.error(key, f"must be a finite number, got {value!r}")
        return value

    def positive(self, key: str, default: float | None = None, *, required: bool = False) -> Any:
        value = self.get(key, float, default, required=required)
        if value is not None and value <= 0:
            raise self.error(key, f"must be greater than 0, got {value!r}")
        return value

    def number(
        self,
        key: str,
        lo: float,
        hi: float,
        default: float | None = None,
        *,
        unit: str = "",
        required: bool = False,
        kind: type = float,
    ) -> Any:
        """A finite number within ``[lo, hi]``, the physically sane range of the field: a value
        outside it is a typo (``885`` kg) or a wrong unit, and is refused naming the range. A
        key written without a value (``angle_arcsec:``) where the field has a default number
        is refused too: it is a number left out, and taking the default would hide that (where
        the default is None, ``timeout_s: null`` is how "computed" is written)."""
        if default is not None and key in self.data and self.data[key] is None:
            raise self.error(
                key, f"has no value: give a number (or leave the key out for {default:g})"
            )
        value = self.get(key, kind, default, required=required)
        if value is None:
            return None
        if not lo <= value <= hi:
            u = f" {unit}" if unit else ""
            raise self.error(key, f"must lie between {lo:g} and {hi:g}{u}, got {show(value)}")
        return value


def show(value: Any, limit: int = 40) -> str:
    """A value for an error message: its repr, cut to ``limit`` characters, on one line."""
    try:
        text = repr(value)
    except ValueError:  # an integer too long for Python to print
        return "a number too long to show"
    return text if len(text) <= limit else text[: limit - 3] + "..."
