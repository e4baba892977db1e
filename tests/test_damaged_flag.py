"""Damaged lines are damaged, not foreign (issue 18): one flipped bit in the flag byte of a
real ALGE start line keeps the descent, with its own start time, flagged."""

from __future__ import annotations

import pytest

from station.timing.impulses import DAMAGED_FLAG, Impulse, Skip
from station.timing.wireformats import AlgeParser
from tests.timing_helpers import write_config

START = b" 0045 C0  11:08:48.8376 00"  # bib 45, finished at 11:09:46.1143


@pytest.fixture(scope="module")
def processor_for(tmp_path_factory, demo_track):
    from station.session.config import load_config
    from station.session.processor import Processor

    tmp = tmp_path_factory.mktemp("cfg")
    cfg = load_config(str(write_config(tmp, "/dev/null", channels={"C0": "PC1", "C1": "PC9"})))
    return lambda: Processor(cfg, demo_track)


def _descents(processor_for, data: bytes):
    """(start, status, photocells, flags) of every descent: framing, parsing, assembling."""
    from station.session.rawlog import Chunk

    proc = processor_for()
    done = proc.feed(Chunk(None, data)) + proc.finish()  # type: ignore[arg-type]  # a capture
    return [(d.start_us, d.status, tuple(d.photocells), tuple(d.flags)) for d in done]


@pytest.mark.parametrize("bit", range(8))
def test_every_single_bit_flip_of_a_start_line_s_flag_keeps_the_descent(real, processor_for, bit):
    data = (real / "alge" / "ALGETdC8001-202002020841.dump").read_bytes()
    assert data.count(START) == 1
    at = data.index(START)
    flipped = bytearray(data)
    flipped[at] ^= 1 << bit
    whole = _descents(processor_for, data)
    got = _descents(processor_for, bytes(flipped))
    assert len(got) == len(whole) > 100
    changed = [(w, g) for w, g in zip(whole, got, strict=True) if w != g]
    assert len(changed) == 1  # only the descent of that start: its flag says why
    (w, g) = changed[0]
    assert g[:3] == w[:3] and w[1] == "complete" and w[2] == ("PC1", "PC9")
    assert f"flag byte {chr(START[0] ^ (1 << bit))!r} damaged, read as an impulse" in g[3][-1]


def test_a_known_flag_still_means_what_it_says():
    p = AlgeParser()
    assert isinstance(p.parse(" 0046 C0  11:09:27.0180 00"), Impulse)
    assert p.parse("c0046 C0  11:09:27.0180 00").__class__.__name__ == "Edit"
    damaged = p.parse("!0046 C0  11:09:27.0180 00")
    assert isinstance(damaged, Impulse) and damaged.flag == DAMAGED_FLAG
    # a computed time stays a computed time whatever its flag
    assert isinstance(p.parse("!0046 RT  00:00:57.27   00"), Skip)
