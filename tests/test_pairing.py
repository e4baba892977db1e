"""Real timers, real days (issues 9 and 11): bibs, several skiers at once, edits, a device clock
that one bad impulse cannot move, TAG memory downloads, disconnects."""

from __future__ import annotations

import datetime as dt
from collections import Counter

import numpy as np
import pytest

from station.errors import InputError
from station.timing.assembly import DescentAssembler
from station.timing.framing import LineFramer
from station.timing.impulses import DAY_US, Edit, Impulse, Skip
from station.timing.wireformats import AlgeParser, TagParser, format_alge, make_parser

S = 1_000_000
PCS = ["PC1", "PC2", "PC3", "PC4", "PC5"]
CH = {"C0": "PC1", "C1": "PC2", "C2": "PC3", "C3": "PC4", "C4": "PC5"}
POS = [0.0, 40.0, 80.0, 120.0, 160.0]


def _lines(path) -> list[str]:
    framer = LineFramer()
    return framer.feed(path.read_bytes()) + framer.flush()


def run_lines(asm: DescentAssembler, parser, lines: list[str]) -> list:
    done = []
    for i, s in enumerate(lines, start=1):
        p = parser.parse(s)
        if isinstance(p, Impulse):
            done += asm.feed(p, i)
        elif isinstance(p, Edit):
            done += asm.edit(p, i)
    return done + asm.close()


def _duration_cs(text: str) -> int:
    h, m, s = text.strip().split(":")
    return round((int(h) * 3600 + int(m) * 60 + float(s)) * 100)


# ----------------------------------------------------------------------------- real ALGE race


@pytest.mark.parametrize(
    ("name", "n_rt"),
    [("ALGETdC8001-202002020841.dump", 126), ("ALGETdC8001-202002021133.dump", 129)],
)
def test_finish_minus_start_per_bib_equals_the_timers_run_time(real, name, n_rt):
    """Several racers on the course at once, paired by bib, with the operator's clears and
    edits applied: the station's finish − start, truncated to 0.01 s, equals every `RT` line
    the timer printed (SOURCES.md: 126 and 129 RT lines)."""
    asm = DescentAssembler(["S", "F"], {"C0": "S", "C1": "F"}, positions_m=[0.0, 400.0],
                           min_speed_ms=1.0)  # fmt: skip
    parser = AlgeParser()
    checked = most = 0
    for i, s in enumerate(_lines(real / "alge" / name), start=1):
        p = parser.parse(s)
        if isinstance(p, Impulse):
            asm.feed(p, i)
            most = max(most, sum(d.bib != "" for d in asm.open))
        elif isinstance(p, Edit):
            asm.edit(p, i)
        elif isinstance(p, Skip) and s[6:8] == "RT" and s[0] != "c":
            bib = s[1:5].lstrip("0")
            d = [d for d in asm.finished + asm.open if d.bib == bib][-1]
            assert d.photocells == ["S", "F"], (i, s, d)
            assert (d.times_us[1] - d.times_us[0]) // 10_000 == _duration_cs(s[10:23]), (i, s)
            checked += 1
    assert checked == n_rt
    assert asm.mode == "bib"
    # the overlap is real: at some moment several racers were on the course
    assert most >= 2


def test_a_cleared_start_leaves_no_descent_and_an_edit_replaces_a_finish(real):
    asm = DescentAssembler(["S", "F"], {"C0": "S", "C1": "F"}, positions_m=[0.0, 400.0])
    done = run_lines(asm, AlgeParser(), _lines(real / "alge" / "ALGETdC8001-202002020841.dump"))
    edits = [e for e in asm.events if ":" in e.reason and e.flag in "ci"]
    cleared = [e for e in edits if e.reason.startswith("cleared: removed")]
    entered = [e for e in edits if e.reason.startswith("edited:") and e.kept]
    assert cleared and entered
    # bib 43: finish 11:02:00.3564 cleared, 11:01:49.1146 entered: the run time is 54.86 s
    d43 = [d for d in asm.finished if d.bib == "43"][-1]
    assert (d43.times_us[1] - d43.times_us[0]) // 10_000 == 5486
    assert d43.status == "complete"
    assert any("cleared at the timer" in f for f in d43.flags)
    # a descent changed by an edit after it finished came out again, to be refitted
    assert sum(d is d43 for d in done) >= 2


# ----------------------------------------------------------------------------- TAG CP540


def test_tag_download_runs_by_bib_dated_by_the_day_counter(real):
    """SOURCES.md: two runs M1 -> M4 with RR 2.477 s and 0.704 s, day 6899 = 2018-11-21;
    a `T+` edit; a live `TN` on day 6994 = 2019-02-24."""
    lines = [s for s in _lines(real / "tag" / "cp540_frames.txt") if not s.startswith("# ")]
    asm = DescentAssembler(["S", "F"], {"M1": "S", "M4": "F"}, positions_m=[0.0, 5.0])
    done = run_lines(asm, TagParser(), lines)
    runs = [d for d in done if d.status == "complete"]
    assert [(d.bib, d.times_us[1] - d.times_us[0]) for d in runs] == [
        ("1", 2_477_000),
        ("2", 704_000),
    ]
    assert dt.date(2000, 1, 1) + dt.timedelta(days=runs[0].day) == dt.date(2018, 11, 21)
    assert runs[0].times_us[0] % DAY_US == (20 * 3600 + 37 * 60 + 44) * S + 136_000
    live = [d for d in done if d.day == 6994]
    assert len(live) == 1 and live[0].status == "aborted"  # a lone live start, nothing after
    assert dt.date(2000, 1, 1) + dt.timedelta(days=6994) == dt.date(2019, 2, 24)
    t_plus = [e for e in asm.events if e.flag == "T+"]
    assert len(t_plus) == 1 and "channel 1 is not a photocell" in t_plus[0].reason


# ----------------------------------------------------------------------------- order + physics


def _descent_times(t0: float, speeds=(8.0, 10.0, 12.0, 13.0)) -> list[float]:
    out = [t0]
    for a, b, v in zip(POS, POS[1:], speeds, strict=False):
        out.append(out[-1] + (b - a) / v)
    return out


def _counter_lines(starts: list[float], drop: set[tuple[int, int]] = frozenset()) -> list[str]:
    events = []
    for n, t0 in enumerate(starts):
        for k, t in enumerate(_descent_times(t0)):
            if (n, k) not in drop:
                events.append((t, f"C{k}"))
    events.sort()
    return [format_alge(ch, round(t * S), i + 1) for i, (t, ch) in enumerate(events)]


def test_counter_mode_overlapping_skiers_assigned_by_order_and_physics():
    """ALGE PC-Timer numbers every impulse: 'auto' sees a counter and pairs by physics.
    Skiers start 6 s apart and take ~16 s: up to three are on the run at once."""
    starts = [36_000.0 + 6 * n for n in range(12)]
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    done = run_lines(asm, AlgeParser(), _counter_lines(starts))
    assert asm.mode == "order"
    assert [d.status for d in done] == ["complete"] * 12
    for d, t0 in zip(sorted(done, key=lambda d: d.number), starts, strict=True):
        want = [round(t * S) for t in _descent_times(t0)]
        assert [abs(a - b) <= 100 for a, b in zip(d.times_us, want, strict=True)] == [True] * 5


def test_an_impulse_no_descent_can_reach_is_rejected_and_joins_nothing():
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0, pairing="order")
    for i, (ch, t) in enumerate([("C0", 100.0), ("C1", 105.0), ("C2", 109.0)], start=1):
        asm.feed(Impulse(ch, round(t * S), 100, "", "", None, ""), i)
    # PC4 0.3 s after PC3: 133 m/s
    asm.feed(Impulse("C3", round(109.3 * S), 100, "", "", None, ""), 4)
    ev = asm.events[-1]
    assert not ev.kept and "implausible" in ev.reason
    asm.feed(Impulse("C3", round(112.5 * S), 100, "", "", None, ""), 5)
    assert asm.events[-1].kept and asm.open[0].photocells == ["PC1", "PC2", "PC3", "PC4"]


def test_bib_pairing_keeps_descents_per_bib():
    asm = DescentAssembler(PCS, CH, positions_m=POS, pairing="bib")
    seq = [("C0", 100, "7"), ("C0", 103, "8"), ("C1", 105, "8"), ("C1", 106, "7"),
           ("C2", 108, "8"), ("C2", 110, "7")]  # fmt: skip
    for i, (ch, t, b) in enumerate(seq, start=1):
        asm.feed(Impulse(ch, t * S, 100, "", b, None, ""), i)
    by = {d.bib: d.times_us for d in asm.open}
    assert by == {"7": [100 * S, 106 * S, 110 * S], "8": [103 * S, 105 * S, 108 * S]}


# ----------------------------------------------------------------------------- the device clock


def test_one_flipped_hour_digit_loses_only_that_impulse():
    """Issue 9: one corrupted time hours ahead used to move the clock and lose the rest of
    the day. A long capture (400 descents, 2 000 impulses) with one hour digit flipped."""
    starts = [8 * 3600.0 + 25 * n for n in range(400)]
    lines = _counter_lines(starts)
    victim = 1001
    s = lines[victim]
    assert s[11] in "0123456789"
    bad = s[:11] + chr(ord(s[11]) ^ 0x04) + s[12:]  # 08:… -> 0<:… would not parse; flip bit 2
    if AlgeParser().parse(bad).__class__ is not Impulse:
        bad = s[:10] + "1" + s[11:]  # 08 -> 18: ten hours ahead
    lines[victim] = bad
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    done = run_lines(asm, AlgeParser(), lines)
    kept = [e.line for e in asm.events if e.kept]
    assert len(kept) == len(lines) - 1 and victim + 1 not in kept
    lost = [e for e in asm.events if e.line == victim + 1][0]
    assert "implausible time" in lost.reason and "did not move" in lost.reason
    assert Counter(d.status for d in done) == {"complete": 400}
    assert [d.missing for d in done if d.missing] == [[PCS[victim % 5]]]


def test_a_long_break_is_confirmed_by_the_next_impulse():
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    lines = _counter_lines([36_000.0, 36_000.0 + 3600])  # an hour's lunch between two descents
    done = run_lines(asm, AlgeParser(), lines)
    assert [d.status for d in done] == ["complete", "complete"]
    assert all(e.kept for e in asm.events)


def test_midnight_wrap_still_works_with_the_jump_rule():
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    done = run_lines(asm, AlgeParser(), _counter_lines([86_395.0]))
    assert done[0].status == "complete"
    assert done[0].times_us[-1] - done[0].times_us[0] == pytest.approx(15.41 * S, abs=0.01 * S)


# ----------------------------------------------------------------------------- edits


def test_a_cleared_middle_time_leaves_its_finished_descent_which_is_refitted():
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    lines = _counter_lines([100.0])
    parser = AlgeParser()
    done = run_lines(asm, parser, lines)
    assert done[0].status == "complete"
    cleared = "c" + lines[2][1:]
    again = asm.edit(parser.parse(cleared), 99)
    assert again == [done[0]] and done[0].photocells == ["PC1", "PC2", "PC4", "PC5"]
    assert done[0].missing == ["PC3"] and done[0].status == "complete"
    assert asm.events[-1].reason.startswith("cleared: removed PC3")
    inserted = asm.edit(parser.parse("i" + lines[2][1:]), 100)
    assert inserted == [done[0]] and done[0].photocells == PCS and done[0].missing == []
    assert "entered descent 1 (refitted)" in asm.events[-1].reason


def test_tag_new_identification_moves_an_impulse_to_another_bib():
    asm = DescentAssembler(PCS, CH, positions_m=POS, pairing="bib")
    asm.feed(Impulse("C0", 100 * S, 10, "", "1", None, ""), 1)
    asm.feed(Impulse("C0", 104 * S, 10, "", "2", None, ""), 2)
    asm.feed(Impulse("C1", 106 * S, 10, "", "1", None, ""), 3)  # the operator meant bib 2
    asm.edit(Edit("new identification", "C1", 106 * S, "T*", "2", ""), 4)
    by = {d.bib: d.photocells for d in asm.open}
    assert by == {"1": ["PC1"], "2": ["PC1", "PC2"]}


def test_disconnect_is_written_on_the_open_descents():
    asm = DescentAssembler(PCS, CH, positions_m=POS)
    asm.feed(Impulse("C0", 100 * S, 100, "", "", None, ""), 1)
    asm.disconnected("read failed")
    assert asm.open[0].flags == ["timer disconnected (read failed)"]


# ----------------------------------------------------------------------------- config


def test_pairing_and_items_in_the_config(tmp_path):
    from station.session.config import load_config
    from tests.timing_helpers import write_config

    cfg = write_config(tmp_path, "/dev/null", extra="descent: {pairing: bib}\n"
                       "items: {12: {ski: A, wax: blue}, '013': {ski: B}}\n")  # fmt: skip
    c = load_config(str(cfg))
    assert c.descent.pairing == "bib"
    assert c.items == {"12": {"ski": "A", "wax": "blue"}, "13": {"ski": "B"}}
    bad = write_config(tmp_path, "/dev/null", extra="descent:\n  pairing: sometimes\n")
    with pytest.raises(InputError, match="pairing") as exc:
        load_config(str(bad))
    assert exc.value.line == 7
    bad = write_config(tmp_path, "/dev/null", extra="items: {twelve: {ski: A}}\n")
    with pytest.raises(InputError, match="bib is a number"):
        load_config(str(bad))


def test_garbage_between_impulses_loses_nothing():
    rng = np.random.default_rng(5)
    lines = _counter_lines([100.0 + 20 * n for n in range(30)])
    mixed = []
    for s in lines:
        mixed.append(s)
        junk = bytes(rng.integers(0, 256, 12, dtype=np.uint8)).decode("latin-1")
        mixed.append(junk.replace("\r", "").replace("\n", ""))
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    done = run_lines(asm, make_parser("alge"), mixed)
    assert [d.status for d in done] == ["complete"] * 30


def test_alge_memory_lines_are_impulses_and_repeats_are_not_doubled():
    """A Timy memory dump (flag m) after the live stream: the descent the station already has is
    not doubled, the one it missed (cable out) is recovered."""
    lines = _counter_lines([100.0, 130.0])
    live = lines[:5]
    memory = ["m" + s[1:] for s in lines]
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0)
    done = run_lines(asm, AlgeParser(), live + memory)
    assert [(d.number, d.status, len(d.photocells)) for d in done] == [
        (1, "complete", 5),
        (2, "complete", 5),
    ]
    assert sum("not doubled" in e.reason for e in asm.events) == 5


def test_a_start_typed_in_without_a_bib_starts_a_descent_and_does_not_replace_one():
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0, pairing="order")
    parser = AlgeParser()
    lines = _counter_lines([100.0, 200.0])
    run_lines(asm, parser, lines[:5])  # descent 1 complete
    asm.edit(parser.parse("i" + lines[5][1:]), 6)  # descent 2's start, typed in
    assert asm.open and asm.open[0].number == 2 and asm.finished[0].times_us[0] == 100 * S
    done = run_lines(asm, parser, lines[6:])
    assert [(d.number, d.status) for d in done] == [(2, "complete")]


# ----------------------------------------------------------------------------- damaged start line


def _flip_unparsable(line: str) -> str:
    """One bit flipped in the time's first colon (':' -> ';'): the line no longer parses."""
    i = line.index(":")
    return line[:i] + chr(ord(line[i]) ^ 1) + line[i + 1 :]


def test_a_descent_whose_start_line_is_bit_flipped_is_recovered_and_fitted(demo_track):
    """Issue 9: one flipped bit in a start line used to lose the skier's whole descent (every
    later impulse "without a start"). The Processor says the line was damaged; the descent
    starts at PC2, is flagged, incomplete, and fitted from the 8 photocells it has."""
    from station.model.physics import Conditions, Params, StraightRun
    from station.session.config import load_config
    from station.session.day import Day
    from station.session.rawlog import Chunk
    from station.session.records import DescentStatus, DescentTimes
    from tests.conftest import SURVEYS

    config = load_config(str(SURVEYS / "demo_station.yaml"))
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    truth = run.solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079))
    t = truth.t
    rng = np.random.default_rng(4)
    lines = []
    for k, t0 in enumerate([36_000.0, 36_060.0]):  # a clean descent, then the damaged one
        noisy = t + np.concatenate([[0], rng.normal(0, 2e-4, len(t) - 1)])
        for i, ti in enumerate(noisy):
            lines.append(format_alge(f"C{i}", round((t0 + ti) * S), 9 * k + i + 1))
    lines[9] = _flip_unparsable(lines[9])
    assert AlgeParser().parse(lines[9]).__class__.__name__ == "Unparsed"
    day = Day.start(config, demo_track)
    done = day.processor.feed(Chunk(0.0, "".join(s + "\r" for s in lines).encode()))
    done += day.processor.finish()
    assert [d.number for d in done] == [1, 2]
    d = done[1]
    assert d.photocells == [f"PC{i}" for i in range(2, 10)] and d.missing == ["PC1"]
    assert d.status == "incomplete"
    assert "start line damaged (line 10): the descent starts at PC2" in d.flags
    assert [e.kept for e in day.processor.events] == [True] * 17
    res = day.analyse(DescentTimes.of(d))
    assert res.descent.status == DescentStatus.INCOMPLETE
    assert res.fit is not None and res.fit.status == "ok", res.fit
    assert res.fit.photocells == d.photocells
    mu = res.fit.mu.value
    assert mu is not None and abs(mu - 0.0085) < 0.002
    # v0 is the speed at the first photocell it has: PC2
    v0 = res.fit.v0.value
    assert v0 is not None and abs(v0 - truth.v[1]) < 0.3


def _feed(asm: DescentAssembler, seq) -> None:
    for ch, t, line, *bib in seq:
        asm.feed(Impulse(ch, round(t * S), 100, "", bib[0] if bib else "", None, ""), line)


def test_a_stray_impulse_without_a_damaged_line_before_it_is_still_rejected():
    """Someone walking through PC3: no damaged line came, so it starts nothing (issue 11)."""
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0, pairing="order")
    _feed(asm, [("C0", 100.0, 1), ("C1", 105.0, 2), ("C2", 109.0, 3), ("C3", 112.0, 4),
                ("C4", 115.0, 5), ("C2", 160.0, 6)])  # fmt: skip
    ev = asm.events[-1]
    assert not ev.kept and ev.reason == "PC3 without a start at PC1"
    assert not asm.open and asm.count == 1


def test_a_damaged_line_too_long_before_a_stray_does_not_start_it():
    """The damaged line came before a descent that was kept, 60 s before the stray: no skier
    reaches PC3 (80 m) that slowly (60 s), so it was not this one's start."""
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0, pairing="order")
    asm.note_damaged(1)
    _feed(asm, [("C0", 100.0, 2), ("C1", 105.0, 3), ("C2", 109.0, 4), ("C3", 112.0, 5),
                ("C4", 115.0, 6), ("C2", 160.0, 7)])  # fmt: skip
    ev = asm.events[-1]
    assert not ev.kept and ev.reason == "PC3 without a start at PC1"


def test_one_damaged_line_starts_one_descent_and_a_lone_one_is_aborted():
    asm = DescentAssembler(PCS, CH, positions_m=POS, min_speed_ms=2.0, pairing="order")
    asm.note_damaged(1)
    # two at PC2 10 s apart: the damaged line could have been either's start, but it was one
    _feed(asm, [("C1", 105.0, 2), ("C1", 115.0, 3)])
    first, second = asm.events
    assert first.kept and first.reason.startswith("start line damaged (line 1)")
    assert not second.kept and second.reason == "second impulse at PC2, 10.000 s after the first"
    assert asm.count == 1
    (d,) = asm.tick(300 * S)
    assert d.status == "aborted" and d.flags[-1].startswith("lone impulse, no impulse for")


def test_a_damaged_line_does_not_start_a_second_descent_of_an_open_bib():
    """With bibs, only a bib with no open descent is recovered: bib 7's second PC2 is not."""
    asm = DescentAssembler(PCS, CH, positions_m=POS, pairing="bib")
    _feed(asm, [("C0", 100.0, 1, "7"), ("C1", 105.0, 2, "7")])
    asm.note_damaged(3)
    _feed(asm, [("C1", 106.0, 4, "7"), ("C1", 107.0, 5, "8")])
    seven, eight = asm.events[-2:]
    assert not seven.kept and seven.reason.startswith("second impulse at PC2")
    assert eight.kept and "start line damaged (line 3)" in eight.reason
    assert {d.bib: d.photocells for d in asm.open} == {"7": ["PC1", "PC2"], "8": ["PC2"]}


def test_a_finish_alone_is_not_recovered_but_its_reason_names_the_damaged_line():
    asm = DescentAssembler(["S", "F"], {"C0": "S", "C1": "F"}, positions_m=[0.0, 400.0])
    asm.note_damaged(1)
    _feed(asm, [("C1", 60.0, 2)])
    ev = asm.events[-1]
    assert not ev.kept and not asm.open
    assert ev.reason == "F without a start at S; line 1 before it was damaged (its start?); " \
        "F alone is nothing to fit"  # fmt: skip
