"""One error type for bad input, so every reader reports file, line and field the same way.

A test engineer at the trackside must see in one line what is wrong and where; a traceback
helps nobody there. The CLI catches :class:`InputError`, prints :meth:`InputError.__str__` and
exits with status 2.
"""

from __future__ import annotations


class InputError(Exception):
    """Bad input, located as precisely as the reader knows: file, line and field."""

    def __init__(
        self,
        message: str,
        *,
        path: str | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.path = path
        self.line = line
        self.field = field

    def __str__(self) -> str:
        where = ""
        if self.path is not None:
            where = str(self.path)
            if self.line is not None:
                where += f":{self.line}"
            where += ": "
        field = f"field {self.field}: " if self.field else ""
        return f"{where}{field}{self.message}"
