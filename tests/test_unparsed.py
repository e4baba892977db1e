"""Every unparsed line is listed in the events, up to a bound that says when it is reached."""

from __future__ import annotations

from station.session import processor as processor_module
from station.session.config import load_config
from station.session.processor import Processor
from station.session.rawlog import Chunk
from tests.timing_helpers import write_config


def _feed_garbage(tmp_path, demo_track, n: int) -> Processor:
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    p = Processor(cfg, demo_track)
    p.feed(Chunk(0.0, b"".join(b"garbage %d\r" % i for i in range(n))))
    return p


def test_more_than_a_thousand_unparsed_lines_are_all_listed(tmp_path, demo_track):
    p = _feed_garbage(tmp_path, demo_track, 5000)
    assert p.counts["unparsed"] == 5000 and len(p.unparsed) == 5000
    assert p.unparsed[-1][2] == "garbage 4999"


def test_beyond_the_bound_one_entry_says_so(tmp_path, demo_track, monkeypatch):
    monkeypatch.setattr(processor_module, "MAX_UNPARSED", 10)
    p = _feed_garbage(tmp_path, demo_track, 50)
    assert p.counts["unparsed"] == 50 and len(p.unparsed) == 11
    assert p.unparsed[-1][0] == 11 and "not listed" in p.unparsed[-1][1]
