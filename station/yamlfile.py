"""YAML loading that remembers line numbers, so a bad key or value is reported where it stands.

``yaml.safe_load`` forgets where things came from. Here mappings load as :class:`LineDict` and
sequences as :class:`LineList`, each knowing the 1-based line of every key or item; the
:class:`Section` helper checks keys and types and raises :class:`InputError` naming file, line
and field.
"""

from __future__ import annotations

from typing import Any

import yaml

from station.errors import InputError


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


class _Loader(yaml.SafeLoader):
    pass


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    out = LineDict()
    out.line = node.start_mark.line + 1
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
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


def load_yaml(path: str) -> Any:
    """Load a YAML file with line numbers; unreadable or malformed files raise InputError."""
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read file: {exc.strerror}", path=path) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file", path=path) from None
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"not valid YAML: {problem}", path=path, line=line) from None


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
                raise InputError(
                    f"unknown key (known keys: {known})",
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
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            return float(value)
        if kind is str and isinstance(value, (int, float)) and not isinstance(value, bool):
            return str(value)
        if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
            raise self.error(key, f"expected {_TYPE_NAMES.get(kind, kind.__name__)}, got {value!r}")
        return value

    def positive(self, key: str, default: float | None = None, *, required: bool = False) -> Any:
        value = self.get(key, float, default, required=required)
        if value is not None and value <= 0:
            raise self.error(key, f"must be greater than 0, got {value!r}")
        return value
