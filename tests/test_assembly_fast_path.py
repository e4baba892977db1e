"""The assembler decides alike whether its impulses come in runs (``feed_run``, cut
anywhere) or one at a time (``feed``): the same events, the same descents, on random days full
of what is not the common case (several skiers on the run, bibs and counters, double
triggers, missed photocells, repeats from the timer's memory, corrupted times, midnight) and
on the real captures, chunked in any way. (``random_day`` serves other tests too.)"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from station.session.config import load_config
from station.session.processor import Processor
from station.session.rawlog import Chunk
from station.survey.load import load_survey
from station.survey.track import build_track
from station.timing.assembly import DescentAssembler
from station.timing.impulses import DAY_US, Impulse
from tests.timing_helpers import write_config

PCS = ["PC1", "PC2", "PC3", "PC4", "PC5", "PC6"]
POS = [0.0, 60.0, 130.0, 210.0, 300.0, 400.0]
CHANNELS = {f"C{i}": pc for i, pc in enumerate(PCS)}


def random_day(rng: np.random.Generator, numbering: str, n: int = 60) -> list[Impulse]:
    """Impulses of ``n`` descents, some overlapping, with the faults a real day has."""
    out: list[tuple[int, Impulse]] = []
    start = 23 * 3600 * 10**6 + 30 * 60 * 10**6  # crosses midnight
    counter = 0
    for k in range(n):
        start += int(rng.uniform(4, 40) * 1e6)  # sometimes the next skier starts early
        speed = rng.uniform(8, 25)
        bib = str(k % 50 + 1)
        for i, x in enumerate(POS):
            if i and rng.random() < 0.05:
                continue  # a missed photocell
            t = start + int(x / speed * 1e6 * rng.uniform(0.97, 1.03))
            counter += 1
            number = bib if numbering == "bib" else str(counter % 10000)
            flag = "?" if rng.random() < 0.03 else ""
            imp = Impulse(f"C{i}", t % DAY_US, 100, flag, number.zfill(4))
            out.append((t, imp))
            if rng.random() < 0.05:  # a double trigger (poles, legs)
                out.append((t + 1, imp._replace(tod_us=(t + 150_000) % DAY_US)))
            if rng.random() < 0.02:  # a corrupted hour digit
                out.append((t + 2, imp._replace(tod_us=(t + 3 * 3600 * 10**6) % DAY_US)))
            if rng.random() < 0.02:  # a stray channel
                out.append((t + 3, imp._replace(channel="C9")))
        if rng.random() < 0.05:  # a lone start (someone walking through the beam)
            out.append((start - 2_000_000, Impulse("C0", (start - 2_000_000) % DAY_US, 100,
                                                   "", "0")))  # fmt: skip
    out.sort(key=lambda p: p[0])
    impulses = [imp for _, imp in out]
    # the timer's memory sent again at the end: repeats are not doubled
    return impulses + impulses[-8:]


def assemble(impulses: list[Impulse], pairing: str, runs: int | None) -> DescentAssembler:
    """The assembler after ``impulses``: one at a time (``runs`` None), or in runs cut at
    random (seeded by ``runs``), each impulse a run of its own where the run stops."""
    asm = DescentAssembler(PCS, CHANNELS, positions_m=POS, pairing=pairing)
    if runs is None:
        for i, imp in enumerate(impulses, start=1):
            asm.feed(imp, i)
            if i % 50 == 0:
                asm.note_damaged(i)  # a line that could not be read
    else:
        rng = np.random.default_rng(runs)
        i = 0
        while i < len(impulses):
            end = min(len(impulses), (i // 50 + 1) * 50, i + int(rng.integers(1, 40)))
            stop = asm.feed_run(impulses[:end], i, i + 1)[0]
            if stop == i:  # a time the next impulse must confirm: on its own
                asm.feed(impulses[i], i + 1)
                stop += 1
            i = stop
            if i % 50 == 0:
                asm.note_damaged(i)
    asm.close()
    return asm


def state(asm: DescentAssembler) -> tuple:
    return (
        [tuple(e) for e in asm.events],
        [dataclasses.astuple(d) for d in asm.finished],
        asm.count,
        asm.mode,
    )


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize(("numbering", "pairing"),
                         [("bib", "auto"), ("counter", "auto"), ("bib", "bib"),
                          ("counter", "order")])  # fmt: skip
def test_runs_decide_as_one_impulse_at_a_time(seed, numbering, pairing):
    impulses = random_day(np.random.default_rng(seed), numbering)
    one = assemble(impulses, pairing, None)
    assert state(assemble(impulses, pairing, seed)) == state(one)
    assert len(one.finished) > 20  # the day was assembled, not rejected wholesale


def test_a_clean_day_is_one_run():
    """A clean day of one skier at a time goes through in one run, the first start and the
    impulse that decides the pairing too."""
    asm = DescentAssembler(PCS, CHANNELS, positions_m=POS, pairing="auto")
    items = [Impulse(f"C{i}", 36_000_000_000 + k * 60_000_000 + int(x / 15 * 1e6), 100, "",
                     str(9 * k + i + 1)) for k in range(20) for i, x in enumerate(POS)]  # fmt: skip
    starts: list[int] = []
    stop, done, kept = asm.feed_run(items, 0, 1, lambda d: starts.append(d.number))
    assert stop == len(items) and kept == len(items) - 1
    assert len(done) == 20 and all(d.status == "complete" for d in done)
    assert starts == list(range(1, 21)) and asm.mode == "order"


REAL = Path(__file__).resolve().parents[2] / "shared" / "fixtures" / "real" / "alge"


@pytest.mark.parametrize("name", ["ALGETdC8001-202002020841.dump", "ALGETdC8001-202002021133.dump"])
def test_the_real_captures_the_same_however_chunked(tmp_path, name):
    """The real days in chunks of 512 bytes (runs) and a line a chunk (one at a time)."""
    path = Path("/work/shared/fixtures/real/alge") / name
    if not path.exists():
        path = REAL / name
    data = path.read_bytes()
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    track = build_track(load_survey(cfg.survey_path))
    results = []
    for cuts in (range(0, len(data), 512), [0, *(k + 1 for k, b in enumerate(data) if b == 13)]):
        proc = Processor(cfg, track)
        edges = [*cuts, len(data)]
        for a, b in zip(edges, edges[1:], strict=False):
            proc.feed(Chunk(None, data[a:b]))  # type: ignore[arg-type]
        proc.finish()
        results.append(state(proc.assembler))
    assert results[0] == results[1]
    assert results[0][0]  # events were made
