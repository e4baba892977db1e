"""Timer wire formats: one line of text -> Impulse, Edit, Skip or Unparsed; and back again.

Parsers are small classes with a ``parse(line)`` method. ALGE's is stateful: a classement
print-out spans several lines that are skipped as a block. Parsing is by fixed columns, as the
devices send them (timing-protocols.md §1.2, §2.1, §3.1). Each protocol has one rule,
``parse``, which decides what any line is, however damaged; it is written so that the common
well-formed impulse line costs a few look-ups in tables (replaying a day means hundreds of
thousands of lines), and ``parse_lines`` is that rule over a chunk's lines, in order.

The ``format_*`` functions write lines byte for byte like the hardware. The simulated timer
uses them, and the tests use them for round trips.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from station.timing.impulses import (
    DAMAGED_FLAG,
    MEMORY_REPEAT,
    Edit,
    Impulse,
    Parsed,
    Skip,
    Unparsed,
    format_tod,
)

# ----------------------------------------------------------------------------- helpers


_TWO = {f"{i:02d}": i for i in range(100)}
_TWO.update({f" {i}": i for i in range(10)})  # a blank-padded hour (TAG)
#: ``HH:MM`` -> µs since midnight (the hour zero- or blank-padded, the minute two digits), and
#: ``SS`` -> µs (zero- or blank-padded): a time of day's fields checked and converted in two
#: look-ups (a replay's every line)
_HH_MM_US = {
    f"{hh}:{m:02d}": (_TWO[hh] * 60 + m) * 60_000_000
    for hh in _TWO
    if _TWO[hh] < 24
    for m in range(60)
}
_SS_US = {ss: s * 1_000_000 for ss, s in _TWO.items() if s < 60}
_POW = [10**i for i in range(7)]


def _tod(text: str) -> tuple[int, int] | None:
    """``HH:MM:SS[.,:]f…`` (fraction right-padded with blanks, hour and second may be
    blank-padded) -> (µs since midnight, resolution µs), or None."""
    n = len(text)
    if n < 8 or text[5] != ":":
        return None
    hm = _HH_MM_US.get(text[0:5])
    ss = _SS_US.get(text[6:8])
    if hm is None or ss is None:
        return None
    base = hm + ss
    if n == 8:
        return base, 1_000_000
    if text[8] not in ".,:":
        return None
    frac = text[9:]
    if not (frac.isascii() and frac.isdigit()):
        frac = frac.rstrip()
        if not frac:
            return base, 1_000_000
        if not _digits(frac):
            return None
    k = len(frac)
    if k > 6:
        return None
    res = _POW[6 - k]
    return base + int(frac) * res, res


def _digits(text: str) -> bool:
    """ASCII digits only. ``str.isdigit`` also accepts the Latin-1 superscripts ``²³¹`` (bytes
    0xB2, 0xB3, 0xB9, which a bit flip makes of ``2``, ``3``, ``9``), which ``int`` refuses:
    a parser that trusted it raised on one flipped bit and ended the recording (issue 9)."""
    return text.isascii() and text.isdigit()


#: an Impulse made without the NamedTuple's Python-level ``__new__``: the same record at a plain
#: tuple's cost (one per line of a replay)
_new = tuple.__new__

#: a number of four digits, which :func:`_digits` takes and ``strip`` leaves as it is
_FOUR_DIGITS = frozenset(f"{i:04d}" for i in range(10_000))

#: ALGE channel columns (``C1 ``, ``c1 ``, ``C1M``, ``C1m``…) -> the channel's name
_ALGE_CHANNEL = {
    c + d + x: "C" + d + ("M" if x != " " else "")
    for c in "cC"
    for d in "0123456789"
    for x in " mM"
}


def _frac(tod_us: int, decimals: int) -> str:
    return format_tod(tod_us, decimals)


class _Parser:
    """A protocol's parser: :meth:`parse` is its rule for one line; ``parse_lines`` is that
    rule over a chunk's lines in order (a replay's, with the parser's state carried from line
    to line as it is by single calls)."""

    parse: Callable[[str], Parsed]

    def parse_lines(self, lines: list[str]) -> list[Parsed]:
        """:meth:`parse` of each line, in order."""
        return list(map(self.parse, lines))


# ----------------------------------------------------------------------------- ALGE


ALGE_EDIT_FLAGS = {
    "c": "cleared",
    "C": "memory time deleted",
    "d": "disqualified",
    "i": "edited",
    "m": MEMORY_REPEAT,
}
ALGE_STATUS_PREFIXES = (
    "TIMY:",
    "CLR",
    "HW_SN",
    "NSF",
    "PROG",
    "PULSE HOLD",
    "ALGE",
    "OK",
    "ACK",
)
ALGE_COMPUTED = {"RT", "TT", "SQ", "DT", "km"}


def alge_checksum(line26: str) -> str:
    """Timy CHK1: low byte of the ASCII sum, as two nibble characters 0x30 + n.

    The algorithm is metarace's; the nibble characters are inferred (timing-protocols.md §1.3).
    """
    total = sum(ord(c) for c in line26) & 0xFF
    return chr(0x30 + (total >> 4)) + chr(0x30 + (total & 0xF))


class AlgeParser(_Parser):
    """ALGE Timy / TdC 8000/8001 PC output: ``yNNNNxCCCxHH:MM:SS.zhtqxGG``.

    A classement print-out (``CLASSEMENT:`` … footer) is skipped as a block. It ends at its
    footer's date line or at the first line that is an impulse: a print-out whose footer was
    lost must not swallow the rest of the day (issue 9: 9 000 lines became 9 impulses)."""

    name = "alge"

    def __init__(self) -> None:
        self.in_printout = False

    def parse(self, line: str) -> Parsed:
        """Any line, however damaged: what it is, or why it is nothing (a chunk of one)."""
        return self.parse_lines((line,))[0]

    def parse_lines(self, lines: Sequence[str]) -> list[Parsed]:
        """Each line in order, however damaged: what it is, or why it is nothing. The line of
        an impulse's columns (the flag, number, channel and time of day, with or without its
        checksum) is read here; a line within a print-out, one with its checksum and the
        other lines, by the two steps below (a blank one where it is first told apart). One
        loop for a chunk: a replay's impulses without a call a line."""
        out: list[Parsed] = []
        add = out.append
        channels, tod, digits, new = _ALGE_CHANNEL, _tod, _digits, _new
        for line in lines:
            s = line
            n = len(s)
            if n == 28 or self.in_printout:
                opened = self._opening(line)
                if not isinstance(opened, str):
                    add(opened)
                    continue
                s = opened
                n = len(s)
            if not (n >= 26 and s[9] == " " and s[23] == " "):
                add(self._not_columns(s, line))
                continue
            chan = s[6:9]
            channel = channels.get(chan)
            if channel is None:
                if line.isspace():
                    add(Skip("blank line", line))
                elif chan[0] in "cC" and digits(chan[1]) or chan[:2] not in ALGE_COMPUTED:
                    add(Unparsed(f"unknown channel {chan!r}", line))
                else:
                    add(Skip(f"computed time ({chan.strip()})", line))
                continue
            t = tod(s[10:23])
            if t is None:
                add(Unparsed(f"time {s[10:23]!r} is not HH:MM:SS.ffff", line))
                continue
            bib = raw_bib = s[1:5]
            if bib not in _FOUR_DIGITS:  # (the common number: a look-up)
                bib = raw_bib.strip()
                if bib and not digits(bib):
                    add(Unparsed(f"start number {raw_bib!r} is not a number", line))
                    continue
            flag = s[0]
            if flag == " ":
                add(new(Impulse, (channel, t[0], t[1], "", bib, None, line)))
            elif flag == "?":
                add(new(Impulse, (channel, t[0], t[1], "?", bib, None, line)))
            elif flag in ALGE_EDIT_FLAGS:
                add(Edit(ALGE_EDIT_FLAGS[flag], channel, t[0], flag, bib, line))
            else:
                # an unknown flag on a line whose channel, time and number read is a damaged
                # byte (one flipped bit of " " or "?"), not a foreign line: skipping it lost
                # the skier's start (issue 18). Kept, flagged; a repeat of a kept impulse (a
                # damaged "c" or "m" line) is not doubled by the assembler.
                add(Impulse(channel, t[0], t[1], DAMAGED_FLAG, bib, None, line))
        return out

    def _opening(self, line: str) -> Parsed | str:
        """A line within a print-out or one with its checksum: what it is, or the text to read
        on (the line, its checksum checked and cut off)."""
        s = line
        n = len(s)
        if self.in_printout:
            if n >= 15 and s[2] == "-" and s[5] == "-":  # the footer's date line "21-11-28  17:04"
                self.in_printout = False
                return Skip("classement print-out", line)
            if not (n in (26, 28) and s[6] in "cC" and s[9] == " " and s[23] == " "):
                return Skip("classement print-out", line)
            self.in_printout = False  # an impulse line: the print-out ended without its footer
        if n == 0 or s.isspace():
            return Skip("blank line", line)
        if n == 28:  # CHK1 checksum appended
            body = s[:26]
            if s[26:28] != alge_checksum(body):
                return Unparsed(
                    f"checksum {s[26:28]!r} does not match {alge_checksum(body)!r}", line
                )
            return body
        return s

    def _not_columns(self, s: str, line: str) -> Parsed:
        """A line (``s``, its checksum cut off) that is not laid out as an impulse's."""
        if not line or line.isspace():
            return Skip("blank line", line)
        n = len(s)
        if n in (5, 6) and s[0] in "ns" and _digits(s[1:5]):
            return Skip("start number shown", line)
        if n == 10 and _tod(s) is not None:
            return Skip("running time", line)
        stripped = s.strip()
        if stripped.startswith("CLASSEMENT"):
            self.in_printout = True
            return Skip("classement print-out", line)
        if stripped.startswith(ALGE_STATUS_PREFIXES):
            return Skip("status line", line)
        if stripped in ("?",):
            return Skip("status line", line)
        return Unparsed("not an ALGE line", line)


def format_alge(
    channel: str, tod_us: int, bib: int | str = 0, flag: str = " ", checksum: bool = False
) -> str:
    """A 26-character ALGE line (28 with CHK1), without the CR.

    ``channel`` is "C0".."C9" or a keypad "C0M"; photocell channels carry 1e-4 s, keypad 1e-2 s.
    """
    ch = channel.upper()
    keypad = ch.endswith("M")
    decimals = 2 if keypad else 4
    tod = _frac(tod_us, decimals).ljust(13)
    b = str(bib).rjust(4, "0")[-4:]
    line = f"{flag[:1] or ' '}{b} {ch:<3} {tod} 00"
    return line + alge_checksum(line) if checksum else line


# ----------------------------------------------------------------------------- TAG Heuer


def tag_cs16(data: str) -> str:
    """THCOM08 CS16: 16-bit sum of the data bytes (a leading # excluded), 4 hex digits."""
    body = data[1:] if data.startswith("#") else data
    return f"{sum(map(ord, body)) & 0xFFFF:04X}"


TAG_EDITS = {
    "T-": "identification removed",
    "T*": "new identification",
    "T+": "inserted",
    "T=": "duplicated",
    "TC": "cancelled",
    "TI": "ideal start",
}
#: messages that are not impulses, with what they are (timing-protocols.md §3.1, SOURCES.md)
TAG_STATUS = {
    "AK": "command acknowledged",
    "ID": "device identification",
    "SN": "serial number, model and version",
    "OP": "run opened",
    "CL": "run closed",
    "DS": "memory download starts",
    "DE": "memory download ends",
    "A-": "download answer without a time",
    "RR": "run time computed by the timer",
    "GR": "result computed by the timer",
    "IR": "result computed by the timer",
    "DR": "result computed by the timer",
    "VE": "speed",
    "&P": "parameter",
    "&S": "system event",
    "!T": "synchro time",
}
#: messages laid out like a time message that are impulses: a live one and one from memory
TAG_IMPULSES = {"TN": "", "AN": "from memory"}


class TagParser(_Parser):
    """TAG Heuer THCOM08 (CP540/545, HL440/940/975): ``Tx NNNN SSSS CC HH:MM:SS.FFFFF DDDDD``.

    ``AN`` lines of a memory download (``DS`` … ``DE``) are impulses with their bib, laid out
    like ``TN``; the day counter DDDDD is days since 2000-01-01 and dates the impulse."""

    name = "tag"

    def parse(self, line: str) -> Parsed:
        """Any line, however damaged: what it is, or why it is nothing."""
        data, tab, cs = line.partition("\t")
        if tab:
            cs = cs.strip()
            if cs and cs != tag_cs16(data):
                return Unparsed(f"checksum {cs!r} does not match {tag_cs16(data)!r}", line)
        s = data.lstrip("#")
        if not s.strip():
            return Skip("blank line", line)
        kind = s[:2]
        if kind in TAG_IMPULSES or kind in TAG_EDITS:
            if len(s) < 30:
                return Unparsed("time message too short", line)
            t = _tod(s[16:30])
            if t is None:
                return Unparsed(f"time {s[16:30]!r} is not HH:MM:SS.FFFFF", line)
            channel = s[13:15].strip()
            if not channel or not channel.isascii() or not channel.isalnum():
                return Unparsed(f"channel {s[13:15]!r} is not a channel", line)
            bib = s[3:7].strip()
            if bib and not _digits(bib):
                return Unparsed(f"candidate {s[3:7]!r} is not a number", line)
            seq = s[8:12].strip()
            if seq and not _digits(seq):
                return Unparsed(f"sequence {s[8:12]!r} is not a number", line)
            rest = s[30:].split()
            day = None
            if rest:
                if not _digits(rest[0]) or len(rest[0]) > 5:
                    return Unparsed(f"day counter {rest[0]!r} is not a number", line)
                day = int(rest[0])
            if kind in TAG_EDITS:
                return Edit(TAG_EDITS[kind], channel, t[0], kind, bib, line, day)
            return _new(Impulse, (channel, t[0], t[1], "" if bib else "?", bib, day, line))
        what = TAG_STATUS.get(kind)
        if what is not None:
            return Skip(what, line)
        return Unparsed("not a THCOM08 line", line)


def format_tag(
    channel: str, tod_us: int, seq: int, bib: int | str = "", day: int = 0, kind: str = "TN"
) -> str:
    """A THCOM08 time message with TAB and CS16, without CR LF (hour blank-padded)."""
    tod = _frac(tod_us, 5)
    if tod[0] == "0":
        tod = " " + tod[1:]
    data = f"{kind} {str(bib):>4} {seq:>4} {channel:>2} {tod} {day:>5}"
    return f"{data}\t{tag_cs16(data)}"


# ----------------------------------------------------------------------------- Microgate


class RacetimeParser(_Parser):
    """Microgate Racetime2 ASCII record: ``QQQQSSSSRRRCCCLLLIOPHHMMSSttt`` (29 characters)."""

    name = "microgate"

    def parse(self, line: str) -> Parsed:
        """Any line, however damaged: what it is, or why it is nothing."""
        s = line
        if not s.strip():
            return Skip("blank line", line)
        if s[0] in "\x02\x03":
            return Skip("transfer header or epilog", line)
        if len(s) != 29 or not _digits(s[0:17]) or not _digits(s[20:29]):
            return Unparsed("not a Racetime2 record", line)
        info, origin = s[17], s[18]
        t = s[20:29]
        h, m, sec, ms = _TWO[t[0:2]], _TWO[t[2:4]], _TWO[t[4:6]], int(t[6:9])
        if h > 23 or m > 59 or sec > 59:
            return Unparsed(f"time {t!r} is not HHMMSSttt", line)
        tod = ((h * 60 + m) * 60 + sec) * 1_000_000 + ms * 1000
        channel = s[14:17]
        bib = s[4:8].lstrip("0")
        if info != "0":
            return Skip(f"not a time of day (info {info!r})", line)
        if origin in "Ss":
            return Skip("skipped time", line)
        return _new(Impulse, (channel, tod, 1000, "", bib, None, line))


def format_racetime(
    channel: str, tod_us: int, counter: int, bib: int = 0, origin: str = "E"
) -> str:
    """A 29-character Racetime2 record, without the CR."""
    s, us = divmod(tod_us, 1_000_000)
    h, rest = divmod(s, 3600)
    m, sec = divmod(rest, 60)
    ch = f"{int(channel):03d}"
    tod = f"{h:02d}{m:02d}{sec:02d}{us // 1000:03d}"
    return f"{counter % 10000:04d}{bib:04d}001{ch}{ch}0{origin} {tod}"


PARSERS = {"alge": AlgeParser, "tag": TagParser, "microgate": RacetimeParser}


def make_parser(protocol: str):
    """A fresh parser for a protocol name from the config."""
    try:
        return PARSERS[protocol]()
    except KeyError:
        raise ValueError(
            f"unknown protocol {protocol!r} (known: {', '.join(sorted(PARSERS))})"
        ) from None
