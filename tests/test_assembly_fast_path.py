"""The assembler's fast paths (the one open descent reaching its next photocell; the next
start with no descent open) decide exactly as the general path: the same events, the same
descents, on random days full of what the general path is for (several skiers on the run, bibs
and counters, double triggers, missed photocells, repeats from the timer's memory, corrupted
times, midnight) and on the real captures, where the parsers' fast paths are compared with
their general paths too. ``_next_photocell`` returning None and ``_start`` returning False
send every impulse down the general path."""

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


def general_only(m: pytest.MonkeyPatch) -> None:
    """Every impulse down the assembler's general path."""
    m.setattr(DescentAssembler, "_next_photocell", lambda *_a: None)
    m.setattr(DescentAssembler, "_start", lambda *_a: False)


def assemble(impulses: list[Impulse], pairing: str, fast: bool, monkeypatch) -> DescentAssembler:
    with monkeypatch.context() as m:
        if not fast:
            general_only(m)
        asm = DescentAssembler(PCS, CHANNELS, positions_m=POS, pairing=pairing)
        for i, imp in enumerate(impulses, start=1):
            asm.feed(imp, i)
            if i % 50 == 0:
                asm.note_damaged(i)  # a line that could not be read
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
def test_the_fast_path_decides_as_the_general_path(seed, numbering, pairing, monkeypatch):
    impulses = random_day(np.random.default_rng(seed), numbering)
    fast = assemble(impulses, pairing, True, monkeypatch)
    general = assemble(impulses, pairing, False, monkeypatch)
    assert state(fast) == state(general)
    assert len(fast.finished) > 20  # the day was assembled, not rejected wholesale


def test_the_fast_path_takes_the_common_case(monkeypatch):
    """On a clean day every impulse goes the fast way, but the first start and the impulse
    that decides the pairing."""
    calls = {"fast": 0, "start": 0}
    real, real_start = DescentAssembler._next_photocell, DescentAssembler._start

    def counted(self, *args):
        done = real(self, *args)
        calls["fast"] += done is not None
        return done

    def counted_start(self, *args):
        started = real_start(self, *args)
        calls["start"] += started
        return started

    monkeypatch.setattr(DescentAssembler, "_next_photocell", counted)
    monkeypatch.setattr(DescentAssembler, "_start", counted_start)
    asm = DescentAssembler(PCS, CHANNELS, positions_m=POS, pairing="auto")
    n = 0
    for k in range(20):
        for i, x in enumerate(POS):
            n += 1
            asm.feed(Impulse(f"C{i}", 36_000_000_000 + k * 60_000_000 + int(x / 15 * 1e6), 100,
                             "", str(n)), n)  # fmt: skip
    assert len(asm.finished) == 20 and all(d.status == "complete" for d in asm.finished)
    # the first descent's second impulse decides the pairing (a counter) the general way
    assert calls["fast"] == 20 * (len(POS) - 1) - 1
    assert calls["start"] == 20 - 1


REAL = Path(__file__).resolve().parents[2] / "shared" / "fixtures" / "real" / "alge"


@pytest.mark.parametrize("name", ["ALGETdC8001-202002020841.dump", "ALGETdC8001-202002021133.dump"])
def test_the_real_captures_give_the_same_either_way(tmp_path, name, monkeypatch):
    path = Path("/work/shared/fixtures/real/alge") / name
    if not path.exists():
        path = REAL / name
    data = path.read_bytes()
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    track = build_track(load_survey(cfg.survey_path))
    results = []
    for fast in (True, False):
        with monkeypatch.context() as m:
            if not fast:  # the parser's general path too, for every line
                general_only(m)
            proc = Processor(cfg, track)
            for k in range(0, len(data), 512):
                proc.feed(Chunk(None, data[k : k + 512]))  # type: ignore[arg-type]
            proc.finish()
            results.append(state(proc.assembler))
    assert results[0] == results[1]
    assert results[0][0]  # events were made
