"""The parsers' fast path (one precompiled pattern for the common impulse line of each protocol)
returns exactly what the general path returns, line by line (``parse``) and for a chunk's lines
in one call (``parse_lines``, a replay's): on every line of the real captures, in order
(ALGE's parser has the state of a classement print-out), on every single-bit flip of real
lines, and on formatted lines with bytes replaced, inserted, deleted or flipped. And the fast
path is taken for the lines it is for (else it would be correct and useless)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from station.timing.framing import LineFramer
from station.timing.impulses import Impulse
from station.timing.wireformats import (
    AlgeParser,
    RacetimeParser,
    TagParser,
    format_alge,
    format_racetime,
    format_tag,
)
from tests.test_parsers_never_raise import PARSERS, mutated

CLASSES = {"alge": AlgeParser, "tag": TagParser, "microgate": RacetimeParser}


def same_both_ways(cls, lines: list[str]) -> int:
    """Parse ``lines`` in order with ``parse`` and with ``parse_general`` (two parsers, each
    keeping its own state); they must agree line by line, type and fields. Returns how many
    lines the fast path took."""
    fast, general = cls(), cls()
    taken = 0
    generals = []
    for i, line in enumerate(lines, start=1):
        if _took_fast_path(cls, fast, line):
            taken += 1
        a, b = fast.parse(line), general.parse_general(line)
        assert type(a) is type(b) and a == b, f"line {i}: {line!r}: {a!r} != {b!r}"
        assert getattr(fast, "in_printout", None) == getattr(general, "in_printout", None)
        generals.append(b)
    # the lines of a chunk in one call (a replay's): the same, line by line
    batch = cls()
    for i, (a, b) in enumerate(zip(batch.parse_lines(lines), generals, strict=True), start=1):
        assert type(a) is type(b) and a == b, f"parse_lines, line {i}: {a!r} != {b!r}"
    assert getattr(batch, "in_printout", None) == getattr(general, "in_printout", None)
    return taken


class _General(Exception):
    pass


def _general(_line: str) -> None:
    raise _General


def _took_fast_path(cls, state, line: str) -> bool:
    """Whether ``parse`` answers ``line`` without the general path (from ``state``'s state)."""
    probe = cls()
    probe.__dict__.update(state.__dict__)
    probe.parse_general = _general
    try:
        probe.parse(line)
    except _General:
        return False
    return True


def capture_lines(path: Path) -> list[str]:
    framer = LineFramer()
    return framer.feed(path.read_bytes()) + framer.flush()


def real_captures(real: Path) -> list[tuple[str, Path]]:
    files = [("alge", p) for p in sorted((real / "alge").iterdir()) if p.is_file()]
    files += [("tag", p) for p in sorted((real / "tag").iterdir()) if p.is_file()]
    return files


def test_every_line_of_every_real_capture(real):
    total = taken = 0
    for protocol, path in real_captures(real):
        lines = capture_lines(path)
        if protocol == "tag":  # the frames of cp540_frames.txt after its comment block
            lines = [s for s in lines if not s.startswith("#")]
        taken += same_both_ways(CLASSES[protocol], lines)
        total += len(lines)
    assert total > 1000
    assert taken > 300  # the real TdC impulse lines take the fast path


def test_every_single_bit_flip_of_real_lines():
    lines = {
        "alge": [" 0001 C0  09:47:40.3259 00", "?0300 C1  08:53:39.4922 00",
                 " 0080 C0M 11:34:22.7700 00"],
        "tag": ["TN       253  1 11:15:33.33261  7803",
                "AN    1    1 M1 20:37:44.13600  6899\t069F",
                "TN   12   34 M4  8:01:02.00010"],
        "microgate": ["000100010012552550E 123456789", format_racetime("001", 86_399_999_000, 9)],
    }  # fmt: skip
    for protocol, originals in lines.items():
        flipped = []
        for line in originals:
            for i in range(len(line)):
                for bit in range(8):
                    flipped.append(line[:i] + chr(ord(line[i]) ^ (1 << bit)) + line[i + 1 :])
        same_both_ways(CLASSES[protocol], originals + flipped)


def test_formatted_lines_take_the_fast_path():
    rng = random.Random(19)
    tods = [rng.randrange(86_400_000_000) for _ in range(300)] + [0, 86_399_999_999]
    alge = [format_alge(f"C{rng.randrange(10)}", t, rng.randrange(10_000), rng.choice(" ?"))
            for t in tods]  # fmt: skip
    tag = [format_tag(rng.choice(["1", "12", "M1"]), t, rng.randrange(10_000),
                      rng.choice(["", "7", "253", "9999"]), rng.randrange(100_000),
                      rng.choice(["TN", "AN"])) for t in tods]  # fmt: skip
    tag += [s.split("\t")[0] for s in tag]
    micro = [format_racetime(f"{rng.randrange(256):03d}", t - t % 1000, rng.randrange(10_000),
                             rng.randrange(10_000)) for t in tods]  # fmt: skip
    for protocol, lines in (("alge", alge), ("tag", tag), ("microgate", micro)):
        assert same_both_ways(CLASSES[protocol], lines) == len(lines), protocol
        assert all(type(CLASSES[protocol]().parse(s)) is Impulse for s in lines)


@pytest.mark.parametrize(
    "protocol,line",
    [
        ("alge", " 0001 C0  09:47:40,3259 00"),  # a decimal comma: the general path reads it
        ("alge", "\xa00001 C0  09:47:40.3259 00"),  # a damaged flag byte: kept, flagged
        ("alge", " 0001 C0  24:47:40.3259 00"),  # no 24th hour
        ("alge", " 0001 C0  09:47:40.3\xb259 00"),  # a superscript digit
        ("alge", " 00 1 C0  09:47:40.3259 00"),
        ("tag", "TN  1 2    1  1 11:15:33.33261  7803"),  # a bib with a blank inside
        ("tag", "TN  253    1  1 11:15:33.33261  7803\t0000"),  # a wrong checksum
        ("tag", "TN  253    1 1  11:15:33.33261  7803"),  # a channel padded on the right
        ("tag", "TN  253    1  1 11:15:33.33261  123456"),  # a day counter too long
        ("microgate", "000100010012552551E 123456789"),  # not a time of day
        ("microgate", "000100010012552550S 123456789"),  # a skipped time
        ("microgate", "000100010012552550s 123456789"),
    ],
)
def test_lines_that_are_not_the_common_shape_go_the_general_way(protocol, line):
    same_both_ways(CLASSES[protocol], [line])


def test_a_print_out_ended_by_an_impulse_line_the_same_both_ways():
    """A classement print-out whose footer was lost ends at the next impulse line (issue 9):
    the line after it is read as a line again, not skipped as the print-out's."""
    lines = ["CLASSEMENT:", " 0001 RTM 00:00:13.39   00 0001", " 0001 C0  09:47:40.3259 00",
             "not an ALGE line", " 0002 C0  09:48:40.3259 00"]  # fmt: skip
    assert same_both_ways(AlgeParser, lines) == 1


@settings(max_examples=500, deadline=None)
@given(st.sampled_from(sorted(PARSERS)), st.data())
def test_mutated_lines_parse_the_same_both_ways(protocol, data):
    cls, make = PARSERS[protocol]
    lines = [data.draw(mutated(make)) for _ in range(6)] + [make(data.draw)]
    same_both_ways(cls, lines)
