"""Bytes from the port -> lines of text, whatever the line end and however the bytes arrive.

Timers end lines with CR (ALGE, Microgate) or CR LF (TAG); captures may have LF. A line may
arrive split across reads, so the framer keeps the unfinished tail. Bytes are decoded as
latin-1, which maps every byte to one character: nothing is lost or replaced, and the raw log
keeps the bytes anyway. A runaway line without terminator (garbage, wrong baud rate) is cut at
MAX_LINE so memory stays bounded; it then parses as nothing and is counted.
"""

from __future__ import annotations

MAX_LINE = 512


class LineFramer:
    """Feed bytes, get complete lines (without their terminators)."""

    def __init__(self) -> None:
        self._tail = ""
        self._after_cr = False

    def feed(self, data: bytes) -> list[str]:
        text = data.decode("latin-1")
        if self._after_cr and text.startswith("\n"):
            text = text[1:]  # the LF of a CR LF split across two reads
        self._after_cr = text.endswith("\r")
        # one whole line and its CR (a live recording's every read): that line, at once
        if self._after_cr and not self._tail and text.find("\r") == len(text) - 1 \
                and "\n" not in text:  # fmt: skip
            return [text[:-1]]
        text = self._tail + text
        if "\r" in text:
            text = text.replace("\r\n", "\n").replace("\r", "\n")
        parts = text.split("\n")
        tail = parts.pop()
        if len(tail) > MAX_LINE:
            # cut by index, each piece copied once: slicing the rest off again and again made
            # one 32 MB chunk without a line end take 41 s (quadratic); now linear
            cut = (len(tail) - 1) // MAX_LINE * MAX_LINE
            parts.extend(tail[i : i + MAX_LINE] for i in range(0, cut, MAX_LINE))
            tail = tail[cut:]
        self._tail = tail
        return parts

    def feed_lines(self, lines: list[str]) -> list[str]:
        """What :meth:`feed` gives for each of ``lines`` fed in turn, each with its CR: lines
        of printable ASCII, a raw log's common records (``station.session.rawlog.Lines``). The
        first finishes the unfinished line (or is the LF of a CR LF: printable, it is not);
        each is a line then (a whole line is never cut). ``lines`` itself when nothing was
        unfinished: a run of records framed without a call a record."""
        if not lines:
            return lines
        self._after_cr = True
        if self._tail:
            lines = [self._tail + lines[0], *lines[1:]]
            self._tail = ""
        return lines

    def feed_run(self, text: str) -> list[str] | None:
        """What :meth:`feed` gives for the reads of a run fed in turn, ``text`` their bytes:
        printable ASCII, each read ending in a CR or not and holding no other, none empty (a
        raw log's common records, ``station.session.rawlog.Lines``): the lines they end, in
        one split. None, and nothing fed, when a line (or the unfinished one) is longer than
        ``MAX_LINE``: :meth:`feed` cuts an unfinished line where a read ends, so such reads go
        one at a time. (No LF: the one after a CR needs no care.)"""
        if not text:
            return []
        parts = (self._tail + text).split("\r")
        if max(map(len, parts)) > MAX_LINE:
            return None
        self._tail = parts.pop()
        self._after_cr = text.endswith("\r")
        return parts

    def flush(self) -> list[str]:
        """The unfinished last line, at the end of a capture."""
        tail, self._tail = self._tail, ""
        return [tail] if tail else []
