"""Descent assembly: the field's quirks, one by one, on the pure state machine."""

from __future__ import annotations

from station.timing.assembly import DescentAssembler
from station.timing.impulses import DAY_US, Impulse

PCS = ["PC1", "PC2", "PC3", "PC4", "PC5"]
CH = {"C0": "PC1", "C1": "PC2", "C2": "PC3", "C3": "PC4", "C4": "PC5"}
S = 1_000_000


def imp(ch: str, t_s: float, day: int | None = None) -> Impulse:
    return Impulse(ch, round(t_s * S) % DAY_US, 100, "", "", day, "")


def feed(asm: DescentAssembler, seq) -> list:
    out = []
    for i, (ch, t) in enumerate(seq, start=1):
        out += asm.feed(imp(ch, t), i)
    return out


def make(**kw) -> DescentAssembler:
    return DescentAssembler(PCS, CH, **{"debounce_s": 0.3, "timeout_s": 30.0, **kw})


def test_a_clean_descent_completes_at_the_last_photocell():
    asm = make()
    done = feed(asm, [("C0", 100), ("C1", 104), ("C2", 107), ("C3", 109), ("C4", 111)])
    assert len(done) == 1
    d = done[0]
    assert d.status == "complete" and d.photocells == PCS and not d.flags
    assert d.times_us == [100 * S, 104 * S, 107 * S, 109 * S, 111 * S]
    assert asm.current is None


def test_double_triggers_collapse_to_the_first_impulse():
    asm = make()
    done = feed(
        asm,
        [("C0", 100), ("C0", 100.05), ("C1", 104), ("C1", 104.2), ("C2", 107), ("C3", 109),
         ("C4", 111), ("C4", 111.1)],
    )  # fmt: skip
    d = done[0]
    assert d.times_us[:2] == [100 * S, 104 * S]
    assert sum("double trigger" in f for f in d.flags) == 3  # the last one after the finish
    dropped = [e for e in asm.events if not e.kept]
    assert [e.line for e in dropped] == [2, 4, 8]
    # the one after the descent ended is collapsed into the finished descent, not a new one
    assert all("double trigger" in e.reason for e in dropped)
    assert dropped[2].descent == 1


def test_a_missed_photocell_leaves_a_flagged_gap():
    d = feed(make(), [("C0", 100), ("C1", 104), ("C3", 109), ("C4", 111)])[0]
    assert d.status == "complete" and d.photocells == ["PC1", "PC2", "PC4", "PC5"]
    assert d.missing == ["PC3"] and d.flags == ["missed PC3"]


def test_a_lone_start_is_aborted_not_a_result():
    asm = make()
    assert feed(asm, [("C0", 100)]) == []
    done = asm.tick(131 * S)
    assert len(done) == 1 and done[0].status == "aborted"
    assert "lone start impulse" in done[0].flags[0]
    assert asm.tick(200 * S) == []


def test_the_next_start_does_not_end_an_open_descent():
    """Issue 11: a second skier may start before the first finishes."""
    asm = make()
    done = feed(asm, [("C0", 100), ("C1", 104), ("C2", 107), ("C0", 120), ("C1", 124)])
    assert done == []
    assert [d.number for d in asm.open] == [1, 2]
    assert asm.open[1].photocells == ["PC1", "PC2"]  # PC2 at 124 s: only descent 2 can take it
    done = asm.close()
    assert [(d.number, d.status) for d in done] == [(1, "incomplete"), (2, "incomplete")]
    assert done[0].missing == ["PC4", "PC5"]


def test_time_out_by_a_later_impulse_and_by_tick():
    asm = make(timeout_s=10.0)
    # 96 s is more than the clock may jump unconfirmed: the next impulse confirms it
    done = feed(asm, [("C0", 100), ("C1", 104), ("C0", 200), ("C1", 204)])
    assert done[0].status == "incomplete"
    assert "no impulse for 100.0 s after PC2" in done[0].flags[0]  # ended by PC2 at 204 s
    asm2 = make(timeout_s=10.0)
    feed(asm2, [("C0", 100), ("C1", 104)])
    assert asm2.tick(113 * S) == []
    assert asm2.tick(115 * S)[0].status == "incomplete"


def test_default_timeout_follows_the_track():
    positions = [0.0, 40.0, 80.0, 120.0, 160.0]
    asm = DescentAssembler(PCS, CH, positions_m=positions, min_speed_ms=2.0)
    assert asm.timeout_us[0] == 40 * S  # 80 m to the photocell after next at 2 m/s
    assert asm.timeout_us[3] == 20 * S


def test_time_of_day_wraps_at_midnight():
    asm = make()
    done = feed(asm, [("C0", 86_398.0), ("C1", 86_399.5), ("C2", 86_401.0), ("C3", 86_403.0),
                      ("C4", 86_405.0)])  # fmt: skip
    d = done[0]
    assert d.status == "complete"
    assert [t - d.times_us[0] for t in d.times_us] == [0, 1_500_000, 3 * S, 5 * S, 7 * S]


def test_the_same_times_of_day_a_day_later_are_new_descents():
    """A repeat of a kept impulse (the timer's memory sent again) is not doubled, but a
    station left running overnight sees the same time of day again on the next day: new."""
    asm = make()
    day = [("C0", 100), ("C1", 104), ("C2", 107), ("C3", 109), ("C4", 111)]
    steps = [(c, t + k * 21_600) for k in range(5) for c, t in day]  # every 6 h, over 24 h
    done = feed(asm, steps)
    assert len(done) == 5 and all(d.status == "complete" for d in done)
    assert done[4].times_us[0] - done[0].times_us[0] == 86_400 * S
    again = asm.feed(imp("C4", 111 + 4 * 21_600), 99)  # the last one repeated
    assert again == [] and "not doubled" in asm.events[-1].reason


def test_out_of_order_impulses_are_rejected_with_their_reason():
    asm = make()
    feed(asm, [("C0", 100), ("C1", 104), ("C2", 107)])
    asm.feed(imp("C1", 108), 4)  # an earlier photocell
    asm.feed(imp("C3", 106), 5)  # an earlier time
    asm.feed(imp("C7", 108), 6)  # no photocell on that channel
    asm.feed(imp("C2", 108), 7)  # a second impulse at the same photocell, after the debounce
    reasons = [e.reason for e in asm.events if not e.kept]
    assert reasons[0] == "out of order: PC2 after PC3"
    # the rejected C1 at 108 s did not move the clock: earlier than C2 at 107 s
    assert reasons[1].startswith("out of order: 1.0000 s earlier")
    assert reasons[2] == "channel C7 is not a photocell"
    assert reasons[3].startswith("second impulse at PC3")
    d = feed(asm, [("C3", 109), ("C4", 111)])[0]
    assert d.photocells == PCS and d.status == "complete"


def test_tag_day_counter_orders_across_midnight():
    asm = make()
    asm.feed(Impulse("C0", 86_399 * S, 10, "", "", 9000, ""), 1)
    asm.feed(Impulse("C1", 3 * S, 10, "", "", 9001, ""), 2)
    assert asm.current.times_us[1] - asm.current.times_us[0] == 4 * S


def _clear(ch: str, t_s: float):
    from station.timing.impulses import Edit

    return Edit("cleared", ch, round(t_s * S) % DAY_US, "c", "")


def test_a_false_finish_cleared_at_the_timer_lets_the_real_finish_join():
    asm = make()
    done = feed(asm, [("C0", 100), ("C1", 104), ("C2", 107), ("C3", 109), ("C4", 110)])
    assert done[0].status == "complete"
    assert asm.edit(_clear("C4", 110), 6) == []  # not a descent yet: open again
    done = asm.feed(imp("C4", 111.5), 7)  # the real finish
    assert len(done) == 1 and done[0].number == 1 and done[0].status == "complete"
    assert done[0].times_us[-1] - done[0].times_us[0] == 11_500_000


def test_a_clear_removes_an_impulse_still_waiting_to_be_confirmed():
    """A start more than a time-out after the last impulse waits for the next one to confirm
    its time; a clear of it then must take it out before it counts."""
    asm = make()
    feed(asm, [("C0", 100), ("C1", 104), ("C2", 107), ("C3", 109), ("C4", 111)])
    asm.feed(imp("C0", 400), 6)  # far from the clock: held
    asm.edit(_clear("C0", 400), 7)
    assert "waiting to be confirmed" in asm.events[-1].reason
    asm.feed(imp("C1", 404), 8)  # far from the clock too: held until the next confirms it
    asm.feed(imp("C2", 407), 9)
    assert not asm.open  # the cleared start opened nothing
    late = [e for e in asm.events if e.line in (8, 9)]
    assert late and all(not e.kept and "without a start" in e.reason for e in late)
