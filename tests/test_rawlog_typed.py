"""Reading a session's raw log a block at a time by the typed decoder gives exactly what reading
every line on its own by the standard library's decoder and the record rule gives: the writer's
every byte value, and records near a record's shape (other numbers, escapes, spacing, fields,
two records on a line, one over two lines), each good or named alike; and the typed decoding
is what reads a clean log. Framing a chunk does not depend on how the bytes arrive."""

from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import station.session.rawlog as rawlog
from station.session.rawlog import RawLogWriter, read_rawlog
from station.timing.framing import LineFramer


def _careful_only(_block):
    raise rawlog._Careful


def both_ways(path, monkeypatch) -> tuple[list, list[str], list, list[str]]:
    """The chunks and warnings of ``path`` read as shipped, and a line at a time by the
    standard library's decoder and the rule (the typed decoding switched off)."""
    typed_w: list[str] = []
    typed = list(read_rawlog(str(path), typed_w))
    with monkeypatch.context() as m:
        m.setattr(rawlog, "_typed", _careful_only)
        careful_w: list[str] = []
        careful = list(read_rawlog(str(path), careful_w))
    return typed, typed_w, careful, careful_w


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
    typed, typed_w, careful, careful_w = both_ways(path, monkeypatch)
    assert typed == careful and typed_w == careful_w
    assert [c.data for c in typed if not c.event] == payloads
    assert all(type(c) is rawlog.Chunk and type(c.t) is float for c in typed)


def test_a_clean_log_is_read_by_the_typed_decoder(tmp_path, monkeypatch):
    path = tmp_path / "raw.jsonl"
    w = RawLogWriter(str(path), header={"port": "loop://"})
    for i in range(200):
        w.write(1_767_600_000.0 + i * 0.3, b" 0001 C0  10:00:00.0000 00\r")
    for i in range(50):  # a TAG line (CR LF), a line with a TAB
        w.write(1_767_600_100.0 + i, b"TN  1 \t00AB\r\n")
    w.event(1_767_600_200.0, "disconnected", "EIO")
    w.close()
    monkeypatch.setattr(rawlog, "_decode", None)  # (the careful way never taken)
    chunks = list(read_rawlog(str(path)))
    assert len(chunks) == 252 and chunks[-1].event == "disconnected"


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
    '{"t":1,"rx":"a"}{"t":2,"rx":"b"}',  # two records on a line
    '{"t":1,"rx":"a"} {"t":2,"rx":"b"}',
    '{"t":1,\n"rx":"a"}',  # one over two lines
    '{"t":1,"rx":"a"}\n\n{"t":2,"rx":"b"}',  # a blank line between
    '{"t":NaN,"rx":"a"}',
    '{"t":1e999,"rx":"a"}',
    '{"t":123456789012345678901234567890,"rx":"a"}',
    '{"t":true,"rx":"a"}',
    '{"t":1,"t":2,"rx":"a"}',
    '{"t":"x","t":2,"rx":"a"}',
    '{"t":1,"rx":"a","rx":null}',
    '{"t":1,"rx":"\\ud800"}',  # a lone surrogate
    '{"t":1,"rx":"\\u0100"}',
    '{"t":1,"rx":"a","event":5}',
    '{"t":1,"rx":"a","detail":[1]}',
    '{"t":1}',
    '[{"t":1,"rx":"a"}]',
    '{"t":1,"event":"x","detail":{"a":1E400}}',
    '{"t":1,"event":"x","detail":{"a":123456789012345678901234567890,"b":-0.0,"a":2}}',
    '{"t":1,"event":"x","detail":' + '{"a":' * 9 + "1" + "}" * 9 + "}",
    '{"t":1,"event":"x","detail":null}',
    '{"t":1,"event":"x"}',
    '{"t":1,"event":5}',
    '\xef\xbb\xbf{"t":1,"rx":"a"}',  # a byte order mark
    '{"t":1,"rx":"a\xe9"}',  # a raw byte beyond ASCII
    '{"t":1,"event":"\xe9"}',
]


@pytest.mark.parametrize("record", NEAR_MISSES)
def test_records_near_a_records_shape_read_the_same_both_ways(tmp_path, monkeypatch, record):
    path = tmp_path / "raw.jsonl"
    good = '{"t":2,"rx":"b\\r"}\n'
    path.write_bytes((good + record + "\n" + good + record).encode("latin-1"))  # torn at the end
    typed, typed_w, careful, careful_w = both_ways(path, monkeypatch)
    assert typed == careful and typed_w == careful_w


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
    """Line by line (a live recording's reads), cut anywhere, or all at once:
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
