"""A long recording stays small and quick: the day keeps no descent's speed curve (the listener
gets it with the fit, the analyser draws it again on request), the impulses' fates go to the
listener and are not kept, and the comparison of the day is computed off the fit path, only
while it is shown, so a descent's fit never waits for the day's joint fit."""

from __future__ import annotations

import sys
import threading
import time

import numpy as np
import pytest

from station.session.acquisition import Acquisition
from station.session.comparing import Comparer
from station.session.config import load_config
from station.session.listener import Listener
from tests.test_acquisition import descent_lines, feed_like_a_reader
from tests.timing_helpers import write_config


class Seen(Listener):
    def __init__(self) -> None:
        self.results: list = []
        self.comparisons: list = []  # DayComparison
        self.fitted = threading.Semaphore(0)

    def result(self, result) -> None:
        self.results.append(result)
        self.fitted.release()

    def comparison(self, day) -> None:
        self.comparisons.append(day)


def wait_fitted(seen: Seen, n: int) -> None:
    for _ in range(n):
        assert seen.fitted.acquire(timeout=60), "a descent was not fitted"


def test_a_recording_keeps_no_speed_curve_and_no_impulse_fates(tmp_path, demo_track):
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    seen = Seen()
    acq = Acquisition.open(cfg, seen)  # threaded, as a recording and the UI run
    feed_like_a_reader(acq, descent_lines(demo_track, [36000, 36060, 36120]))
    wait_fitted(seen, 3)
    assert acq.day.processor.events == []  # handed to the listener, not kept
    acq.close()
    handed = {r.number: r for r in seen.results}
    kept = acq.results()
    assert [r.speed_x for r in kept] == [None, None, None]
    for r in kept:  # the listener had it; the analyser draws the same again
        x, v = acq.speed_curve(r)
        assert np.array_equal(x, handed[r.number].speed_x)
        assert np.array_equal(v, handed[r.number].speed_v)

    # a replay in line (the report draws every curve, --events lists every fate) keeps both
    replayed = Acquisition.open(cfg, threaded=False)
    feed_like_a_reader(replayed, descent_lines(demo_track, [36000, 36060, 36120]))
    replayed.close()
    assert all(r.speed_x is not None for r in replayed.results())
    assert len(replayed.day.processor.events) == 27


def test_the_comparison_is_computed_only_while_shown(tmp_path, demo_track):
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    seen = Seen()
    acq = Acquisition.open(cfg, seen, compare=True)
    try:
        feed_like_a_reader(acq, descent_lines(demo_track, [36000, 36060, 36120]))
        wait_fitted(seen, 3)
        time.sleep(0.8)
        assert seen.comparisons == []  # not shown: not computed
        acq.show_comparison(True)
        deadline = time.monotonic() + 30
        while not seen.comparisons:
            assert time.monotonic() < deadline, "no comparison while shown"
            time.sleep(0.05)
        assert seen.comparisons[-1].result is not None  # the joint fit
        acq.show_comparison(False)
        n = len(seen.comparisons)
        feed_like_a_reader(acq, descent_lines(demo_track, [36180]))
        wait_fitted(seen, 1)
        time.sleep(0.8)
        assert len(seen.comparisons) == n  # closed again: the new descent is not compared
    finally:
        acq.close()


#: the comparison's process, 3 s slower per comparison (the day's joint fit at 2000 descents)
SLOW_COMPARER = (
    sys.executable, "-c",
    "import time, station.session.comparing as c\n"
    "fit = c.live_comparison\n"
    "def slow(*args):\n    time.sleep(3.0)\n    return fit(*args)\n"
    "c.live_comparison = slow\n"
    "c.main()\n",
)  # fmt: skip


def test_a_fit_never_waits_for_the_comparison(tmp_path, demo_track, monkeypatch):
    """The day's joint fit takes seconds at 2000 descents: here it takes 3 s more, and a
    descent ending while it runs is fitted and handed out meanwhile."""
    monkeypatch.setattr(Comparer, "command", SLOW_COMPARER)
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    seen = Seen()
    acq = Acquisition.open(cfg, seen, compare=True)
    assert acq.comparer is not None
    try:
        acq.show_comparison(True)
        lines = descent_lines(demo_track, [36000, 36060])
        feed_like_a_reader(acq, lines[:1])
        wait_fitted(seen, 1)
        deadline = time.monotonic() + 30
        while not acq.comparer.busy:  # the comparison is running
            assert time.monotonic() < deadline, "the comparison did not start"
            time.sleep(0.01)
        t0 = time.monotonic()
        feed_like_a_reader(acq, lines[1:])
        wait_fitted(seen, 1)
        assert time.monotonic() - t0 < 2.5
        assert seen.comparisons == []  # the comparison was still under way
    finally:
        acq.close()


def test_a_recording_keeps_its_fits_in_the_session_store_not_in_memory(tmp_path, demo_track):
    """A recording into a session keeps each descent's fit in ``fits.jsonl`` (4 kB a descent
    in memory otherwise): the result reads it back, the same fit the listener was handed; a
    store that lost it (the file removed) is no lost fit: it is computed again."""
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    seen = Seen()
    session = tmp_path / "session"
    acq = Acquisition.open(cfg, seen, session_dir=str(session))
    feed_like_a_reader(acq, descent_lines(demo_track, [36000, 36060, 36120]))
    wait_fitted(seen, 3)
    acq.close()
    handed = {r.number: r for r in seen.results}
    kept = acq.results()
    assert [r.number for r in kept] == [1, 2, 3]
    for r in kept:
        assert r.kept_fit is None and r.stored is not None and r.has_fit
        assert handed[r.number].kept_fit is not None  # the listener shows it at once
        assert r.fit == handed[r.number].fit
    # the rows the results CSV was written from are those of the fits read back
    assert [r.row.mu for r in kept] == [r.fit.mu.value for r in kept]

    (session / "fits.jsonl").unlink()
    again = kept[1].fit
    assert again is not None
    assert again.mu.value == pytest.approx(handed[2].fit.mu.value, rel=1e-9)
    assert again.mu.ci90 == pytest.approx(handed[2].fit.mu.ci90, rel=1e-6)

    # without a session (no store) the fits stay in memory, as before
    seen = Seen()
    plain = Acquisition.open(cfg, seen)
    feed_like_a_reader(plain, descent_lines(demo_track, [36000]))
    wait_fitted(seen, 1)
    plain.close()
    (res,) = plain.results()
    assert res.stored is None and res.kept_fit is not None and res.fit is res.kept_fit


def test_a_long_day_keeps_one_copy_of_its_times_and_still_takes_edits(tmp_path, demo_track):
    """The assembler keeps every descent (an edit at the timer may name any) and every kept
    time (a repeat from the timer's memory is not doubled), compactly: a finished descent
    shares the day's frozen copy of its times, older kept times move to a sorted array. A
    repeat of the first descent's impulse after 70 more is still not doubled, and a time
    cleared at the timer in descent 2 still leaves it, refitted."""
    from station.session.rawlog import Chunk
    from station.timing.assembly import SEEN_RECENT

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    acq = Acquisition.open(cfg, threaded=False)
    n = SEEN_RECENT + 6
    lines = descent_lines(demo_track, [36000 + 60 * k for k in range(n)])
    t = 1.7e9
    for d in lines:
        for line in d:
            t += 1
            acq.receive(Chunk(t, line.encode()))
    asm = acq.day.processor.assembler
    assert len(asm.finished) == n and asm._seen_old  # older times in the sorted arrays
    first = acq.day.results[1].descent
    assert asm.finished[0].times_us is first.times_us  # one copy: the day's

    events = len(acq.day.processor.events)
    acq.receive(Chunk(t + 1, ("m" + lines[0][1][1:]).encode()))  # descent 1's PC2 again
    (ev,) = acq.day.processor.events[events:]
    assert not ev.kept and "not doubled" in ev.reason
    acq.receive(Chunk(t + 2, ("c" + lines[1][2][1:]).encode()))  # clear descent 2's PC3
    acq.close()
    second = acq.day.results[2]
    assert "PC3" in second.descent.missing and len(second.descent.times_us) == 8
    assert second.row.photocells_used == 8 and second.fit is not None
    assert acq.day.results[1].descent.times_us == first.times_us
    assert len(acq.results()) == n


def test_descents_with_the_same_metadata_share_one_record(tmp_path, demo_track):
    """Metadata given "from descent 1 on" is overlaid on the config's for every descent: the
    rows of a day share one record for equal metadata, not one each."""
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    acq = Acquisition.open(cfg, threaded=False)
    acq.add_metadata({"ski": "A", "wax": "blue"}, from_descent=1)
    acq.add_metadata({"wax": "red"}, from_descent=3)
    feed_like_a_reader(acq, descent_lines(demo_track, [36000, 36060, 36120, 36180]))
    acq.close()
    metas = [r.row.metadata for r in acq.results()]
    assert [(m.ski, m.wax) for m in metas] == [("A", "blue")] * 2 + [("A", "red")] * 2
    assert metas[0] is metas[1] and metas[2] is metas[3] and metas[1] is not metas[2]


def test_a_finish_cleared_in_the_same_chunk_leaves_the_descent_open_to_take_the_next(
    tmp_path, demo_track
):
    """The chunk that finishes a descent also clears its finish at the timer: the descent is
    open again (its times stay lists the assembler can change) and takes the real finish."""
    from station.session.rawlog import Chunk
    from station.timing.wireformats import format_alge

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    acq = Acquisition.open(cfg, threaded=False)
    (lines,) = descent_lines(demo_track, [36000])
    false_finish = lines[-1]
    h, m, sec = false_finish[10:23].split(":")
    tod_us = (int(h) * 3600 + int(m) * 60) * 10**6 + round(float(sec) * 1e6)
    real_finish = format_alge("C8", tod_us + 5000, 10) + "\r"  # 5 ms later
    acq.receive(Chunk(1.7e9, "".join(lines + ["c" + false_finish[1:]]).encode()))
    acq.receive(Chunk(1.7e9 + 1, real_finish.encode()))
    acq.close()
    (res,) = acq.results()
    assert res.descent.status == "complete" and len(res.descent.times_us) == 9
    assert res.descent.times_us[-1] % 86_400_000_000 == tod_us + 5000
    assert any("cleared at the timer" in f for f in res.descent.flags)


@pytest.mark.parametrize("seed", range(8))
def test_settled_descents_and_sorted_kept_times_decide_as_before(seed, monkeypatch):
    """A day assembled as a recording does it (every finished descent settled on its frozen
    copy, older kept times moved to the sorted arrays) gives the same events and descents as
    the assembler alone, on random days with several skiers, double triggers, repeats from
    the timer's memory (of the day's first descents too) and clears and inserts at the timer
    of times from any earlier descent."""
    import dataclasses

    import station.timing.device_clock as assembly  # (SEEN_RECENT is read there)
    from station.session.records import DescentTimes
    from station.timing.assembly import DescentAssembler
    from station.timing.impulses import DAY_US, Edit
    from tests.test_assembly_fast_path import CHANNELS, PCS, POS, random_day

    rng = np.random.default_rng(seed)
    impulses = random_day(rng, "bib" if seed % 2 else "counter", n=80)
    feed: list = []
    for k, imp in enumerate(impulses):
        feed.append(imp)
        if k > 40 and rng.random() < 0.08:  # an edit of an earlier impulse
            old = impulses[int(rng.integers(0, k))]
            kind = "cleared" if rng.random() < 0.6 else "inserted"
            tod = old.tod_us if kind == "cleared" else (old.tod_us + 40_000) % DAY_US
            feed.append(Edit(kind, old.channel, tod, "c", old.bib))
    feed += impulses[:10]  # the timer's memory from the start of the day
    monkeypatch.setattr(assembly, "SEEN_RECENT", 4)

    def run(settle: bool) -> tuple:
        asm = DescentAssembler(PCS, CHANNELS, positions_m=POS, pairing="auto")
        for i, x in enumerate(feed, start=1):
            done = asm.edit(x, i) if isinstance(x, Edit) else asm.feed(x, i)
            for d in done if settle else ():
                d.settle(DescentTimes.of(d))
        done = asm.close()
        lists = [{k: list(v) if isinstance(v, tuple) else v
                  for k, v in dataclasses.asdict(d).items()} for d in asm.finished]  # fmt: skip
        return [tuple(e) for e in asm.events], lists, asm.count, bool(asm._seen_old)

    settled, alone = run(True), run(False)
    assert settled == alone
    assert settled[3] and len(settled[1]) > 40
    assert any("(refitted)" in str(e) for e in settled[0])  # edits changed finished descents
