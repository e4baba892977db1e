"""Timer protocols: real ALGE captures, published example lines, round trips, garbage."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from station.timing.framing import LineFramer
from station.timing.impulses import Edit, Impulse, Skip, Unparsed
from station.timing.wireformats import (
    AlgeParser,
    RacetimeParser,
    TagParser,
    alge_checksum,
    format_alge,
    format_racetime,
    format_tag,
    make_parser,
)


def _lines(path) -> list[str]:
    framer = LineFramer()
    return framer.feed(path.read_bytes()) + framer.flush()


def _naive_counts(lines: list[str]) -> tuple[Counter, int]:
    """An independent count from the fixed columns alone: impulses are 26-character lines with
    flag blank or '?' on a C-channel; edits are the same lines flagged c, C, d or i."""
    imp: Counter = Counter()
    edits = 0
    for s in lines:
        if len(s) != 26 or s[6] not in "cC":
            continue
        ch = s[6:9].strip().upper()
        if s[0] in " ?":
            imp[ch] += 1
        elif s[0] in "cCdi":
            edits += 1
    return imp, edits


@pytest.mark.parametrize("name", ["ALGETdC8001-202002020841.dump", "ALGETdC8001-202002021133.dump"])
def test_real_tdc_captures(real, name):
    lines = _lines(real / "alge" / name)
    parser = AlgeParser()
    parsed = [parser.parse(s) for s in lines]
    counts = Counter(p.channel for p in parsed if isinstance(p, Impulse))
    edits = [p for p in parsed if isinstance(p, Edit)]
    expected, expected_edits = _naive_counts(lines)
    assert counts == expected
    assert len(edits) == expected_edits
    assert not [p for p in parsed if isinstance(p, Unparsed)]
    # RT/TT are computed run and total times, not impulses
    assert sum(1 for p in parsed if isinstance(p, Skip) and "computed" in p.reason) > 100


def test_real_tdc_first_capture_in_numbers(real):
    parser = AlgeParser()
    parsed = [parser.parse(s) for s in _lines(real / "alge" / "ALGETdC8001-202002020841.dump")]
    imps = [p for p in parsed if isinstance(p, Impulse)]
    assert Counter(p.channel for p in imps) == {"C0": 133, "C1": 164, "C0M": 2}
    assert Counter(p.kind for p in parsed if isinstance(p, Edit)) == {"cleared": 4, "edited": 2}
    assert sum(p.flag == "?" for p in imps) == 43
    first = next(p for p in imps if p.channel == "C0")
    assert first.tod_us == (8 * 3600 + 53 * 60 + 39) * 10**6 + 492_200
    assert first.resolution_us == 100 and first.bib == "0300" and first.flag == "?"
    keypad = next(p for p in imps if p.channel == "C0M")
    assert keypad.resolution_us == 100 and keypad.tod_us % 10_000 == 0


def test_classement_printout_is_skipped_as_a_block(real):
    parser = AlgeParser()
    parsed = [parser.parse(s) for s in _lines(real / "alge" / "ALGEClassement_Runtime_Run1.txt")]
    assert all(isinstance(p, Skip) for p in parsed)
    assert not parser.in_printout  # the footer's date line ended the block
    # a normal impulse after the print-out parses again
    assert isinstance(parser.parse(" 0001 C0  10:15:02.1234 00"), Impulse)


@pytest.mark.parametrize(
    ("line", "kind"),
    [
        ("n0007", Skip),
        ("s0008", Skip),
        ("TIMY: 480170000", Skip),
        ("10:15:13.2", Skip),  # running time
        ("CLR", Skip),
        ("PROG: PC-TIMER", Skip),
        (" 0001 RT  00:00:59.76   00", Skip),
        ("c0005 C1  10:15:12.0457 00", Edit),
        ("i0043 C1  11:01:49.1146 00", Edit),
        ("?0006 C1M 10:15:40.12   00", Impulse),
        ("?0034 C1M 21:46:48.1    00", Impulse),
        (" 0015 c0  15:43:49,8863 00", Impulse),  # the manuals' decimal comma, lower-case c
        (" 0001 C9  25:00:00.0000 00", Unparsed),
        (" 0001 X1  10:00:00.0000 00", Unparsed),
        ("\x01\x02garbage\xff", Unparsed),
        ("", Skip),
    ],
)
def test_alge_line_kinds(line, kind):
    assert isinstance(AlgeParser().parse(line), kind)


def test_alge_checksum_examples_and_mismatch():
    assert alge_checksum(" 0001 C0  09:47:40.3259 00") == ">1"
    assert alge_checksum("?0001 C1  09:06:42.7183 00") == "?>"
    p = AlgeParser()
    assert isinstance(p.parse(" 0001 C0  09:47:40.3259 00>1"), Impulse)
    bad = p.parse(" 0001 C0  09:47:40.3259 00>2")
    assert isinstance(bad, Unparsed) and "checksum" in bad.reason


def test_tag_published_examples():
    p = TagParser()
    imp = p.parse("TN       253  1 11:15:33.33261  7803\t068E")
    assert isinstance(imp, Impulse)
    assert (imp.channel, imp.tod_us, imp.resolution_us, imp.day) == ("1", 40_533_332_610, 10, 7803)
    keypad = p.parse("TN         4 M1  8:35:09.75300  8830")
    assert isinstance(keypad, Impulse) and keypad.channel == "M1"
    assert keypad.tod_us == (8 * 3600 + 35 * 60 + 9) * 10**6 + 753_000
    assert isinstance(p.parse("#TN 0016 0072 05 12:13:56.7800 12345\t06D9"), Impulse)
    assert isinstance(p.parse("TN       253  1 11:15:33.33261  7803\t068F"), Unparsed)
    assert isinstance(p.parse("AK C\t00EF"), Skip)  # 0x41 + 0x4B + 0x20 + 0x43 = 0x00EF
    assert isinstance(p.parse("AK C"), Skip)
    assert isinstance(p.parse("TC       253  1 11:15:33.33261  7803"), Edit)


def test_racetime_published_example():
    imp = RacetimeParser().parse("000100010012552550M 123456789")
    assert isinstance(imp, Impulse)
    assert (imp.channel, imp.bib, imp.resolution_us) == ("255", "1", 1000)
    assert imp.tod_us == (12 * 3600 + 34 * 60 + 56) * 10**6 + 789_000
    assert isinstance(RacetimeParser().parse("000100010012552551M 000012345"), Skip)  # net time


def test_round_trips_for_every_protocol():
    rng = np.random.default_rng(3)
    for tod in rng.integers(0, 86_400_000_000, 300):
        a = format_alge("C3", int(tod), 17)
        assert AlgeParser().parse(a).tod_us == int(tod) // 100 * 100
        assert AlgeParser().parse(format_alge("C3", int(tod), 17, checksum=True)).tod_us == (
            int(tod) // 100 * 100
        )
        t = format_tag("12", int(tod), 5, "", 9000)
        assert TagParser().parse(t).tod_us == int(tod) // 10 * 10
        r = format_racetime("007", int(tod), 5)
        assert RacetimeParser().parse(r).tod_us == int(tod) // 1000 * 1000


def test_garbage_never_raises():
    rng = np.random.default_rng(0)
    for name in ("alge", "tag", "microgate"):
        parser = make_parser(name)
        framer = LineFramer()
        for _ in range(300):
            data = bytes(rng.integers(0, 256, int(rng.integers(1, 80)), dtype=np.uint8))
            for line in framer.feed(data):
                assert isinstance(parser.parse(line), (Impulse, Edit, Skip, Unparsed))


def test_unknown_protocol():
    with pytest.raises(ValueError, match="unknown protocol 'omega'"):
        make_parser("omega")


def test_a_printout_without_footer_ends_at_the_next_impulse(real):
    """Issue 9: a CLASSEMENT block whose footer was lost swallowed the rest of the day."""
    lines = _lines(real / "alge" / "ALGEClassement_Runtime_Run1.txt")
    cut = [s for s in lines if "ALGE TIMING" not in s and "TdC" not in s and "DEU" not in s
           and "-11-" not in s]  # fmt: skip
    parser = AlgeParser()
    assert all(isinstance(parser.parse(s), Skip) for s in cut)
    assert parser.in_printout
    after = [format_alge("C0", 36_000_000_000 + i * 10**6, i) for i in range(5)]
    assert all(isinstance(parser.parse(s), Impulse) for s in after)
    assert not parser.in_printout


def test_tag_cp540_frames_every_message_understood(real):
    """SOURCES.md: 14 real CP540 frames, checksums verify; AN impulses with their bib."""
    lines = [s for s in _lines(real / "tag" / "cp540_frames.txt") if not s.startswith("# ")]
    parsed = [TagParser().parse(s) for s in lines]
    assert not [p for p in parsed if isinstance(p, Unparsed)]
    an = [p for p in parsed if isinstance(p, Impulse) and p.line.startswith("AN")]
    assert [(p.bib, p.channel) for p in an] == [("1", "M1"), ("1", "M4"), ("2", "M1"), ("2", "M4")]
    assert an[0].tod_us == (20 * 3600 + 37 * 60 + 44) * 10**6 + 136_000 and an[0].day == 6899
    assert an[1].tod_us - an[0].tod_us == 2_477_000 and an[3].tod_us - an[2].tod_us == 704_000
    edits = [p for p in parsed if isinstance(p, Edit)]
    assert [(e.kind, e.bib, e.channel) for e in edits] == [("inserted", "1", "1")]
    live = [p for p in parsed if isinstance(p, Impulse) and p.line.startswith("TN")]
    assert [(p.bib, p.channel, p.day) for p in live] == [("2", "M1", 6994)]
    reasons = {p.reason for p in parsed if isinstance(p, Skip)}
    assert {
        "device identification",
        "memory download starts",
        "memory download ends",
        "run time computed by the timer",
        "result computed by the timer",
    } <= reasons
