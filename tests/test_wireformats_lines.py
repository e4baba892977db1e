"""What each protocol's one rule makes of lines that are and are not the common shape, a line at
a time and a chunk's lines in one call (``parse_lines``, a replay's, with the parser's state
carried across): formatted lines read back as the impulses they were made from; a decimal
comma, a damaged flag byte, a 24th hour, a superscript digit, a wrong checksum each get their
own answer; a print-out whose footer was lost ends at the next impulse line."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from station.timing.framing import LineFramer
from station.timing.impulses import DAMAGED_FLAG, Impulse, Parsed, Skip, Unparsed
from station.timing.wireformats import (
    AlgeParser,
    RacetimeParser,
    TagParser,
    format_alge,
    format_racetime,
    format_tag,
)

CLASSES = {"alge": AlgeParser, "tag": TagParser, "microgate": RacetimeParser}


def one_by_one(cls, lines: list[str]) -> list[Parsed]:
    """``parse`` of each line in turn, and the same from ``parse_lines`` in one call."""
    single = cls()
    each = [single.parse(line) for line in lines]
    batch = cls()
    assert batch.parse_lines(lines) == each
    assert getattr(batch, "in_printout", None) == getattr(single, "in_printout", None)
    return each


def test_formatted_lines_read_back():
    rng = random.Random(19)
    for _ in range(300):
        t = rng.randrange(86_400_000_000)
        ch, bib, flag = f"C{rng.randrange(10)}", rng.randrange(1, 10_000), rng.choice(" ?")
        (p,) = one_by_one(AlgeParser, [format_alge(ch, t, bib, flag, rng.random() < 0.3)])
        assert type(p) is Impulse
        assert (p.channel, p.tod_us, p.flag, p.bib) == (ch, t - t % 100, flag.strip(), f"{bib:04d}")
        day, tag_bib = rng.randrange(100_000), rng.choice(["", "7", "253"])
        (p,) = one_by_one(
            TagParser, [format_tag("M1", t, 12, tag_bib, day, rng.choice(["TN", "AN"]))]
        )
        assert type(p) is Impulse
        assert (p.channel, p.tod_us, p.bib, p.day) == ("M1", t - t % 10, tag_bib, day)
        (p,) = one_by_one(RacetimeParser, [format_racetime("007", t - t % 1000, 9, bib)])
        assert type(p) is Impulse and (p.channel, p.tod_us) == ("007", t - t % 1000)


@pytest.mark.parametrize(
    "protocol,line,kind,what",
    [
        ("alge", " 0001 C0  09:47:40,3259 00", Impulse, ""),  # a decimal comma
        ("alge", "\xa00001 C0  09:47:40.3259 00", Impulse, DAMAGED_FLAG),  # kept, flagged
        ("alge", " 0001 C0  24:47:40.3259 00", Unparsed, ""),  # no 24th hour
        ("alge", " 0001 C0  09:47:40.3\xb259 00", Unparsed, ""),  # a superscript digit
        ("alge", " 00 1 C0  09:47:40.3259 00", Unparsed, ""),  # a blank in the number
        ("alge", " 0001 RT  00:00:13.39   00", Skip, ""),
        ("alge", " 0001 C0  09:47:40.3259 0000", Unparsed, ""),  # a wrong checksum
        ("tag", "TN  1 2    1  1 11:15:33.33261  7803", Unparsed, ""),  # a blank in the bib
        ("tag", "TN  253    1  1 11:15:33.33261  7803\t0000", Unparsed, ""),  # a wrong checksum
        ("tag", "TN  253    1 1  11:15:33.33261  7803", Impulse, ""),  # a channel padded right
        ("tag", "TN  253    1  1 11:15:33.33261  123456", Unparsed, ""),  # day counter too long
        ("microgate", "000100010012552551E 123456789", Skip, ""),  # not a time of day
        ("microgate", "000100010012552550S 123456789", Skip, ""),  # a skipped time
        ("microgate", "000100010012552550s 123456789", Skip, ""),
    ],
)
def test_lines_that_are_not_the_common_shape(protocol, line, kind, what):
    (p,) = one_by_one(CLASSES[protocol], [line])
    assert type(p) is kind, p
    if kind is Impulse and what:
        assert p.flag == what


def test_a_print_out_ended_by_an_impulse_line():
    """A classement print-out whose footer was lost ends at the next impulse line (issue 9):
    the line after it is read as a line again, not skipped as the print-out's."""
    lines = ["CLASSEMENT:", " 0001 RTM 00:00:13.39   00 0001", " 0001 C0  09:47:40.3259 00",
             "not an ALGE line", " 0002 C0  09:48:40.3259 00"]  # fmt: skip
    kinds = [type(p) for p in one_by_one(AlgeParser, lines)]
    assert kinds == [Skip, Skip, Impulse, Unparsed, Impulse]


def test_every_line_of_every_real_capture_one_by_one_and_in_chunks(real):
    """The real captures' lines, a chunk at a time as a replay cuts them, read as one by one."""
    impulses = 0
    for protocol, folder in (("alge", "alge"), ("tag", "tag")):
        for path in sorted((Path(real) / folder).iterdir()):
            framer = LineFramer()
            lines = framer.feed(path.read_bytes()) + framer.flush()
            each = one_by_one(CLASSES[protocol], lines)
            parser = CLASSES[protocol]()
            chunks = [parser.parse_lines(lines[k : k + 7]) for k in range(0, len(lines), 7)]
            assert [p for chunk in chunks for p in chunk] == each
            impulses += sum(type(p) is Impulse for p in each)
    assert impulses > 300  # the real TdC impulse lines
