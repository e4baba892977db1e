"""Reading a session's raw log and framing its chunks: the fast paths for the common record and
the common chunk (one whole line) give exactly what the general paths give, and are taken.

``read_rawlog`` reads a record of the writer's own shape (a plain decimal host time, printable
ASCII and the escapes of CR, LF and TAB) without the JSON decoder; every other record goes the
general way, with its checks and warnings. ``LineFramer.feed`` answers a chunk that is one
whole line ending in CR at once."""

from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import station.session.rawlog as rawlog
from station.session.rawlog import RawLogWriter, read_rawlog
from station.timing.framing import LineFramer


def both_ways(path, monkeypatch) -> tuple[list, list[str], list, list[str]]:
    """The chunks and warnings of ``path`` read as it is, and with the fast path off."""
    fast_w: list[str] = []
    fast = list(read_rawlog(str(path), fast_w))
    with monkeypatch.context() as m:
        m.setattr(rawlog, "_COMMON", lambda _raw: None)
        m.setattr(rawlog, "_ONE_LINE", lambda _raw: None)
        general_w: list[str] = []
        general = list(read_rawlog(str(path), general_w))
    return fast, fast_w, general, general_w


def test_written_records_read_the_same_both_ways(tmp_path, monkeypatch):
    rng = random.Random(19)
    path = tmp_path / "raw.jsonl"
    w = RawLogWriter(str(path), header={"port": "loop://", "protocol": "alge"})
    payloads = [
        bytes(range(256)),
        b"",
        b"\\",
        b'"',
        b"\\r",
        b"\r\n\t",
        b" 0001 C0  10:00:00.0000 00\r",
    ]
    payloads += [bytes(rng.randrange(256) for _ in range(rng.randrange(40))) for _ in range(300)]
    payloads += [bytes(rng.choice(b" 0123456789:.?C\r\n\t\\\"") for _ in range(30))
                 for _ in range(300)]  # fmt: skip
    times = [0, 0.5, 1e-7, 7, 1_767_600_000.123456, 9_999_999_999.5]
    for i, p in enumerate(payloads):
        w.write(times[i % len(times)] if i < 50 else 1_767_600_000 + rng.random() * 1e5, p)
        if i % 97 == 0:
            w.event(1_767_600_000.0 + i, "disconnected", "EIO")
    w.close()
    fast, fast_w, general, general_w = both_ways(path, monkeypatch)
    assert fast == general and fast_w == general_w
    assert [c.data for c in fast if not c.event] == payloads
    assert all(type(c) is rawlog.Chunk and type(c.t) is float for c in fast)


def test_the_fast_path_reads_the_common_records(tmp_path, monkeypatch):
    path = tmp_path / "raw.jsonl"
    w = RawLogWriter(str(path), header={"port": "loop://"})
    for i in range(200):
        w.write(1_767_600_000.0 + i * 0.3, b" 0001 C0  10:00:00.0000 00\r")
    w.close()
    w = RawLogWriter(str(path))
    for i in range(50):  # a TAG line (CR LF), a line with a TAB
        w.write(1_767_600_100.0 + i, b"TN  1 \t00AB\r\n")
    w.close()
    taken: dict[str, list[bool]] = {"_ONE_LINE": [], "_COMMON": []}
    for name in taken:
        real = getattr(rawlog, name)

        def counted(raw: bytes, real=real, name=name):
            m = real(raw)
            taken[name].append(m is not None)
            return m

        monkeypatch.setattr(rawlog, name, counted)
    chunks = list(read_rawlog(str(path)))
    assert len(chunks) == 251  # all but the session header the fast way:
    assert sum(taken["_ONE_LINE"]) == 200 and sum(taken["_COMMON"]) == 50


NEAR_MISSES = [
    '{"t":0123.5,"rx":"a"}',  # a leading zero: not JSON
    '{"t":1e3,"rx":"a"}',
    '{"t":12345678901,"rx":"a"}',  # beyond MAX_T
    '{"t":-1,"rx":"a"}',
    '{"t":1.,"rx":"a"}',
    '{"t":1,"rx":"a\\u00e9"}',
    '{"t":1,"rx":"a\\u20ac"}',  # beyond latin-1
    '{"t":1,"rx":"a\\\\r"}',  # an escaped backslash, then r
    '{"t":1,"rx":"a\\"b"}',
    '{"t":1,"rx":"a\\x"}',  # not an escape JSON knows
    '{"t":1,"rx":"a\x7f"}',
    '{"t":1,"rx":"a\tb"}',  # a raw TAB inside a string: not JSON
    '{"t": 1, "rx": "a"}',
    '{"rx":"a","t":1}',
    '{"t":1,"rx":"a","event":"x"}',
    '{"t":1,"rx":"a"} ',
    '{"t":1,"rx":"a"}\r',
    '{"t":1,"rx":"a"',
    '{"t":1,"rx":"a\\r\\n\\t"}',
    '{"t":1.5,"rx":""}',
]


@pytest.mark.parametrize("record", NEAR_MISSES)
def test_records_near_the_common_shape_read_the_same_both_ways(tmp_path, monkeypatch, record):
    path = tmp_path / "raw.jsonl"
    good = '{"t":2,"rx":"b\\r"}\n'
    path.write_bytes((good + record + "\n" + good + record).encode("latin-1"))  # torn at the end
    fast, fast_w, general, general_w = both_ways(path, monkeypatch)
    assert fast == general and fast_w == general_w


def frame(chunks: list[bytes]) -> list[str]:
    f = LineFramer()
    out = [line for c in chunks for line in f.feed(c)]
    return out + f.flush()


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.text(alphabet=" 0123456789C:.?x", max_size=30), max_size=12),
    st.lists(st.sampled_from(["\r", "\n", "\r\n"]), min_size=12, max_size=12),
    st.lists(st.integers(1, 40), max_size=20),
)
def test_framing_does_not_depend_on_how_the_bytes_arrive(lines, ends, cuts):
    """Line by line (a live recording's reads, the fast path), cut anywhere, or all at once:
    the same lines."""
    data = "".join(s + e for s, e in zip(lines, ends, strict=False)).encode("latin-1")
    whole = frame([data])
    per_line = frame([(s + e).encode() for s, e in zip(lines, ends, strict=False)])
    pieces, k = [], 0
    for c in cuts:
        pieces.append(data[k : k + c])
        k += c
    pieces.append(data[k:])
    assert per_line == whole == frame(pieces)
    assert whole == [s for s in data.decode().replace("\r\n", "\n").replace("\r", "\n").split("\n")
                     ][: len(whole)]  # fmt: skip


@pytest.mark.parametrize("name", ["ALGETdC8001-202002020841.dump", "ALGETdC8001-202002021133.dump"])
def test_a_session_of_a_real_capture_replays_the_same_all_fast_or_all_general(
    real, tmp_path, monkeypatch, name
):
    """The real capture's lines recorded one record each (as a recording writes them), then
    replayed with every fast path (raw log, framing, parser, assembler) and with none: the
    same events, descents and counts."""
    import dataclasses

    from station.session.config import load_config
    from station.session.processor import Processor
    from station.session.replay import replay_chunks
    from station.survey.load import load_survey
    from station.survey.track import build_track
    from station.timing.assembly import DescentAssembler
    from station.timing.wireformats import AlgeParser
    from tests.timing_helpers import write_config

    framer = LineFramer()
    lines = framer.feed((real / "alge" / name).read_bytes()) + framer.flush()
    session = tmp_path / "session"
    session.mkdir()
    w = RawLogWriter(str(session / "raw.jsonl"), header={"port": "loop://"})
    for k, line in enumerate(lines):
        w.write(1_580_630_000.0 + 0.25 * k, (line + "\r").encode("latin-1"))
    w.close()
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    track = build_track(load_survey(cfg.survey_path))
    states = []
    for fast in (True, False):
        with monkeypatch.context() as m:
            if not fast:
                m.setattr(rawlog, "_COMMON", lambda _raw: None)
                m.setattr(rawlog, "_ONE_LINE", lambda _raw: None)
                m.setattr(AlgeParser, "parse", AlgeParser.parse_general)
                m.setattr(DescentAssembler, "_next_photocell", lambda *_a: None)
                m.setattr(DescentAssembler, "_start", lambda *_a: False)
            proc = Processor(cfg, track)
            for chunk in replay_chunks(str(session)):
                proc.feed(chunk)
            proc.finish()
            asm = proc.assembler
            states.append((
                [tuple(e) for e in asm.events], [dataclasses.astuple(d) for d in asm.finished],
                proc.unparsed, proc.line_counts(), proc.offset_us,
                [proc.start_host.get(n) for n in range(1, asm.count + 1)],
            ))  # fmt: skip
    assert states[0] == states[1]
    assert len(states[0][1]) > 20
