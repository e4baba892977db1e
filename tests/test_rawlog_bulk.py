"""The raw log read as a replay reads it (``read_rawlog_bulk``: runs of reads as ``Lines``, what
``station replay SESSION --no-fit`` reads) gives, record by record, what reading every line on
its own by the standard library's decoder and the record rule gives: the same chunks, the same
warnings, the same error at the same point; and a replay fed either way (runs, or a chunk a
record) leaves the same descents, events, counts, host times of starts and ``--no-fit`` output.

The logs: written by the writer (common ALGE and Microgate lines, TAG lines with CR LF, events,
reads of several lines or half a line, every byte value), then mutated by hypothesis (bytes
flipped to anything, line ends and quotes among them; ranges deleted or repeated; garbage
inserted; cut anywhere, a torn last record), read in blocks of a few bytes up to many records
so that records are cut by a block's end everywhere, and with the log's limit reached while
read."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import random
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import station.session.rawlog as rawlog
import station.session.replay as replay_mod
from station.errors import InputError
from station.session.processor import Processor
from station.session.rawlog import Chunk, Lines, RawLogWriter, read_rawlog, read_rawlog_bulk
from station.timing.framing import MAX_LINE, LineFramer
from station.timing.wireformats import format_alge
from tests import test_assembly_batch as batch
from tests.test_assembly_batch import ALGE_2, mutate, session_chunks, simulated_alge

configs = batch.configs  # the fixtures of the batch's tests: configs on the demo survey,
run_times = batch.run_times  # the demo run's crossing times


def expand(items: list) -> list[Chunk]:
    """The chunks a bulk read stands for, a run of common records one chunk a record."""
    out: list[Chunk] = []
    for item in items:
        if type(item) is Lines:
            assert item.t and len(item.t) == len(item.rx)  # no empty run
            assert all(type(t) is float for t in item.t)
            chunks = item.chunks()
            assert all(c.data and b"\r" not in c.data[:-1] for c in chunks)
            if item.ends is None:
                assert all(c.data.endswith(b"\r") for c in chunks)
            else:
                assert "".join(c.data.decode() for c in chunks) == item.text
                assert item.ends == [c.t for c in chunks if c.data.endswith(b"\r")]
            out += chunks
        else:
            assert type(item) is Chunk
            out.append(item)
    return out


def _careful_only(_block):
    raise rawlog._Careful


def read_both(path, block: int | None = None):
    """(chunks, warnings, error) read a line at a time by the standard library's decoder and
    the rule (the typed decoding of blocks switched off), and as shipped, in blocks of
    ``block`` bytes, runs expanded (checked to fit :class:`Lines`); the items as shipped."""
    got = []
    items: list = []
    for shipped in (False, True):
        with pytest.MonkeyPatch.context() as mp:
            if shipped and block is not None:
                mp.setattr(rawlog, "BLOCK", block)
            if not shipped:
                mp.setattr(rawlog, "_typed", _careful_only)
            warnings: list[str] = []
            chunks: list = []
            error = None
            try:
                for c in (read_rawlog_bulk if shipped else read_rawlog)(str(path), warnings):
                    chunks.append(c)
            except InputError as exc:
                error = str(exc)
            if shipped:
                items = chunks
                chunks = expand(chunks)
            got.append((chunks, warnings, error))
    return got[0], got[1], items


def assert_same_reads(path, **kw) -> list:
    careful, bulk, items = read_both(path, **kw)
    for k, (a, b) in enumerate(zip(careful[0], bulk[0], strict=False)):
        assert a == b, f"record {k} differs: {a!r} {b!r}"
    assert careful == bulk
    return items


def writer_log(path, seed: int, n: int = 120) -> None:
    """A session's raw log as the writer writes it: mostly common records, and the others."""
    rng = random.Random(seed)
    w = RawLogWriter(str(path), header={"port": "loop://", "protocol": "alge"})
    t = 1_767_600_000.0 + rng.random()
    for k in range(n):
        t += rng.choice([0.3, 0.25, 1e-6, 12.5, 0.1234567])
        line = format_alge(f"C{k % 9}", 36_000_000_000 + k * 1_234_567, k + 1)
        roll = rng.random()
        if roll < 0.7:
            w.write(t, (line + "\r").encode())
        elif roll < 0.75:
            w.write(t, b"\r")  # an empty line
        elif roll < 0.8:
            w.write(t, (line + "\r" + line + "\r").encode())  # two lines in one read
        elif roll < 0.85:
            w.write(t, line[:7].encode())  # half a line, the rest in the next read
            w.write(t + 0.001, (line[7:] + "\r").encode())
        elif roll < 0.87:  # reads as a USB adapter gives them: pieces of lines
            data = (line + "\r" + line[: rng.randrange(len(line))]).encode()
            cuts = sorted(rng.sample(range(1, len(data)), 3))
            for x, y in zip([0, *cuts], [*cuts, len(data)], strict=True):
                w.write(t, data[x:y])
                t += 0.004
        elif roll < 0.88:
            w.write(t, b"TN  1 \t00AB\r\n")
        elif roll < 0.91:
            w.write(t, bytes(rng.randrange(256) for _ in range(rng.randrange(12))))
        elif roll < 0.94:
            w.event(t, rng.choice(["timeout", "disconnected", "connected"]), "EIO")
        elif roll < 0.96:
            w.write(float(rng.randrange(3)) if roll > 0.95 else t, b"12:00:00.0\r")
        else:  # a line longer than the framer keeps, over reads
            for _ in range(rng.randrange(1, 4)):
                w.write(t, b"x" * rng.randrange(100, 400))
            w.write(t, b"\r")
    w.write(t + 1, b" 0999 C0  10:00")  # the last line unfinished (it ends the replay)
    w.close()


def test_a_written_log_reads_the_same_and_in_runs(tmp_path):
    path = tmp_path / "raw.jsonl"
    writer_log(path, 1, n=2000)
    for block in (None, 1, 7, 64, 1000):
        items = assert_same_reads(path, block=block)
        if block in (None, 1000):  # the common records came in runs, not a chunk each
            runs = [len(i.t) for i in items if type(i) is Lines]
            assert sum(runs) > 600 and max(runs) > 5  # (one record in eight is another)


def test_a_clean_log_is_one_run_a_block(tmp_path):
    path = tmp_path / "raw.jsonl"
    w = RawLogWriter(str(path), header={"port": "loop://"})
    for k in range(5000):
        w.write(1_767_600_000.0 + 0.3 * k, (format_alge("C1", k * 1000, k) + "\r").encode())
    w.close()
    items = assert_same_reads(path)
    assert type(items[0]) is Chunk and items[0].event == "session"
    assert len(items) <= 3 and sum(len(i.t) for i in items[1:]) == 5000


def test_a_log_of_other_records_reads_the_same_and_comes_back_to_runs(tmp_path):
    """A TAG timer's reads (CR LF: no common record) are read the careful way, block after
    block without a check but now and then; ALGE lines after them come in runs again."""
    path = tmp_path / "raw.jsonl"
    w = RawLogWriter(str(path), header={"port": "loop://"})
    for k in range(3000):
        w.write(1_767_600_000.0 + k, b"TN  1 \t00AB\r\n")
    for k in range(3000):
        w.write(1_767_700_000.0 + k, (format_alge("C1", k * 1000, k) + "\r").encode())
    w.close()
    for block in (None, 2000):
        items = assert_same_reads(path, block=block)
        runs = [len(i.t) for i in items if type(i) is Lines]
        assert 2000 < sum(runs) <= 3000


@settings(max_examples=250, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(
    seed=st.integers(0, 10_000),
    ops=st.lists(
        st.tuples(st.integers(0, 5), st.integers(0, 10**6), st.integers(0, 255)), max_size=8
    ),
    cut=st.one_of(st.none(), st.integers(0, 10**6)),
    block=st.integers(1, 600),
)
def test_mutated_logs_read_the_same_both_ways(tmp_path_factory, seed, ops, cut, block):
    """Bytes flipped, ranges deleted, repeated, garbage or line ends inserted, the log cut
    anywhere (a torn last record); read in blocks of 1 to 600 bytes (records cut by a block's
    end everywhere)."""
    path = tmp_path_factory.mktemp("bulk") / "raw.jsonl"
    writer_log(path, seed, n=40)
    data = bytearray(path.read_bytes())
    for op, at, value in ops:
        at %= len(data) + 1
        if op == 0 and data:  # a byte flipped to anything
            data[at % len(data)] = value
        elif op == 1 and data:  # to one the reader cares about
            data[at % len(data)] = b'\n"\\r{}:,.0 \xff'[value % 12]
        elif op == 2:  # a range deleted
            del data[at : at + value % 80]
        elif op == 3:  # a range repeated
            data[at:at] = data[at : at + value % 120]
        elif op == 4:  # garbage
            data[at:at] = bytes((value * k + 7) % 256 for k in range(value % 9 + 1))
        else:  # a common record inserted where it may not start a line
            data[at:at] = b'{"t":1.5,"rx":"a\\r"}\n'[value % 5 :]
    if cut is not None:
        del data[cut % (len(data) + 1) :]
    path.write_bytes(bytes(data))
    assert_same_reads(path, block=block)


@pytest.mark.parametrize("block", [5, 100, 4096])
def test_long_and_overlong_records_the_same(tmp_path, monkeypatch, block):
    """A record longer than the block, and one longer than ``MAX_RECORD`` (passed over
    unread), ended or at the end."""
    monkeypatch.setattr(rawlog, "MAX_RECORD", 300)
    good = '{"t":2,"rx":"b\\r"}\n'
    long_rec = '{"t":3,"rx":"' + "x" * 250 + '\\r"}\n'
    over = '{"t":4,"rx":"' + "y" * 1000 + '\\r"}\n'
    for tail in ("", over[:-1], over[:200], long_rec[:-1]):
        path = tmp_path / "raw.jsonl"
        path.write_text(good * 3 + long_rec + good + over + good * 2 + over + tail)
        assert_same_reads(path, block=block)


def test_a_hostile_log_reads_the_same(tmp_path):
    """benchmarks/hostile_rawlog.py's session, smaller: a record of 600 kB of garbage without
    a line end among a day's records, then bad
    records (more than are named), a blank line and a torn last one."""
    rec = '{{"t":{},"rx":" {:04d} C{}  10:00:00.{:04d} 00\\r"}}\n'
    day = [rec.format(1_770_000_000 + i, i, i % 9, i) for i in range(200)]
    path = tmp_path / "raw.jsonl"
    path.write_text(
        "".join(day)
        + '{"t":1770000300,"rx":"' + "x" * (600 * 1024)
        + "".join(day)
        + '{"t": NaN, "rx": "\\u20ac"}\n' * 15
        + "\n"
        + "".join(day[:50])
        + '{"t":1770000400,"rx":" 0001 C'
    )  # fmt: skip
    items = assert_same_reads(path)
    assert sum(len(i.t) for i in items if type(i) is Lines) >= 399


@pytest.mark.parametrize("limit", [0, 19, 20, 100, 150, 1000])
def test_the_log_grown_past_its_limit_stops_both_at_the_same_line(tmp_path, monkeypatch, limit):
    """The limit reached while read (the file grew): the same records before the same error."""
    path = tmp_path / "raw.jsonl"
    path.write_text(
        '{"t":2,"rx":"b\\r"}\n' * 30 + '{"t":1,"event":"x"}\n' + '{"t":2,"rx":"c\\r"}\n' * 30
    )
    monkeypatch.setattr(rawlog, "open_regular", lambda p, _m, _w: open(p, "rb"))  # noqa: SIM115
    monkeypatch.setattr(rawlog, "MAX_RAWLOG", limit)
    careful, bulk, _ = read_both(path, block=64)
    assert careful == bulk and careful[2] is not None and "larger than" in careful[2]


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.binary(max_size=6), max_size=4),
    st.lists(st.text(alphabet="ab 09:", min_size=1, max_size=200), max_size=8),
    st.lists(st.booleans(), min_size=8, max_size=8),
)
def test_a_run_is_framed_as_read_by_read(before, reads, ends):
    """``LineFramer.feed_run``: what ``feed`` gives read by read, after any bytes (half a line,
    a CR, a CR LF, a line too long); None and nothing changed when ``feed`` would cut a line
    too long where a read ended."""
    reads = [r + "\r" if e else r for r, e in zip(reads, ends, strict=False)]
    f, g = LineFramer(), LineFramer()
    got = [x for b in before for x in f.feed(b)]
    want = [x for b in before for x in g.feed(b)]
    state = (f._tail, f._after_cr)
    run = f.feed_run("".join(reads))
    want += [x for r in reads for x in g.feed(r.encode())]
    if run is None:
        assert (f._tail, f._after_cr) == state
        assert max(len(x) for x in (f._tail + "".join(reads)).split("\r")) > MAX_LINE
        got += [x for r in reads for x in f.feed(r.encode())]
    else:
        got += run
    assert got == want
    assert f.feed(b"\nz\r") == g.feed(b"\nz\r") and f.flush() == g.flush()
    if all(r.endswith("\r") for r in reads):  # a line a read: feed_lines, the lines as they are
        f, g = LineFramer(), LineFramer()
        got = [x for b in before for x in f.feed(b)] + f.feed_lines([r[:-1] for r in reads])
        want = [x for b in before for x in g.feed(b)]
        want += [x for r in reads for x in g.feed(r.encode())]
        assert got == want
        assert f.feed(b"\nz\r") == g.feed(b"\nz\r") and f.flush() == g.flush()


# ----------------------------------------------------------------------------- replays


def write_session(path, chunks: list[Chunk]) -> None:
    w = RawLogWriter(str(path), header={"port": "loop://", "protocol": "alge"})
    for c in chunks:
        if c.event:
            w.event(c.t, c.event, c.detail)
        else:
            w.write(c.t, c.data)
    w.close()


def replayed(cfg, track, path, bulk: bool) -> dict:
    proc = Processor(cfg, track)
    warnings: list[str] = []
    out = proc.feed_chunks((read_rawlog_bulk if bulk else read_rawlog)(str(path), warnings))
    out += proc.finish()
    asm = proc.assembler
    return {
        "out": [dataclasses.astuple(d) for d in out],
        "events": [tuple(e) for e in asm.events],
        "finished": [dataclasses.astuple(d) for d in asm.finished],
        "open": [dataclasses.astuple(d) for d in asm.open],
        "count": (asm.count, asm.mode, asm.clock, asm._day_offset),
        "lines": (proc.lines, proc.impulses, dict(proc.counts), proc.unparsed),
        "starts": [proc.start_host.get(n) for n in range(1, asm.count + 1)],
        "host": (proc.offset_us, list(proc._recent), proc._chunk_t, proc.connection),
        "state": (proc._latest_start, proc.resolution_us, proc.framer._tail),
        "warnings": warnings,
    }


def assert_same_replays(cfg, track, path, monkeypatch, block: int, run: int) -> dict:
    monkeypatch.setattr(rawlog, "BLOCK", block)
    monkeypatch.setattr("station.session.processor.SESSION_RUN", run)
    careful = replayed(cfg, track, path, bulk=False)
    bulk = replayed(cfg, track, path, bulk=True)
    for i, (x, y) in enumerate(zip(careful["events"], bulk["events"], strict=False)):
        assert x == y, f"event {i} (line {x[0]}) differs:\n{x}\n{y}"
    for key in careful:
        assert careful[key] == bulk[key], f"{key} differs"
    return bulk


@pytest.mark.parametrize("pairing", ["auto", "bib"])
@pytest.mark.parametrize("name", ["ALGETdC8001-202002020841.dump", "ALGETdC8001-202002021133.dump"])
def test_real_days_as_sessions_replay_the_same(real, configs, demo_track, tmp_path, monkeypatch,
                                               name, pairing):  # fmt: skip
    framer = LineFramer()
    lines = framer.feed((real / "alge" / name).read_bytes()) + framer.flush()
    for seed, block, run in ((0, 256 * 1024, 4096), (1, 3000, 4096), (2, 200, 50)):
        path = tmp_path / f"raw-{seed}.jsonl"
        write_session(path, session_chunks(lines, seed))
        got = assert_same_replays(configs("alge", ALGE_2, pairing), demo_track, path,
                                  monkeypatch, block, run)  # fmt: skip
        assert len(got["finished"]) > 20 and all(h is not None for h in got["starts"][:50])


@pytest.mark.parametrize("seed", range(6))
def test_written_logs_replay_the_same(configs, demo_track, tmp_path, monkeypatch, seed):
    """The writer's logs above (lines in pieces, lines too long for the framer over several
    reads, events, every byte value) replayed in blocks down to a few records."""
    path = tmp_path / "raw.jsonl"
    writer_log(path, seed, n=600)
    for block, run in ((256 * 1024, 4096), (997, 33), (150, 5)):
        got = assert_same_replays(configs("alge"), demo_track, path, monkeypatch, block, run)
        assert got["lines"][1] > 300


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(
    seed=st.integers(0, 10_000),
    numbering=st.sampled_from(["bib", "counter"]),
    pairing=st.sampled_from(["auto", "bib", "order"]),
    ops=st.lists(
        st.tuples(st.integers(0, 7), st.integers(0, 10**6), st.integers(0, 10**6)), max_size=30
    ),
    block=st.integers(20, 5000),
    run=st.integers(1, 300),
    cut=st.one_of(st.none(), st.integers(0, 10**6)),
)
def test_simulated_and_mutated_sessions_replay_the_same(configs, demo_track, run_times,
                                                        tmp_path_factory, seed, numbering,
                                                        pairing, ops, block, run, cut):  # fmt: skip
    """Simulated days (overlapping skiers, time-outs, a disconnect, reads of two lines and of
    half a line), their lines mutated, the log cut anywhere (a torn last record)."""
    lines = mutate(simulated_alge(run_times, seed, numbering, n=15), ops)
    path = tmp_path_factory.mktemp("sess") / "raw.jsonl"
    write_session(path, session_chunks(lines, seed))
    if cut is not None:
        data = path.read_bytes()
        path.write_bytes(data[: cut % (len(data) + 1)])
    with pytest.MonkeyPatch.context() as m:
        assert_same_replays(configs("alge", None, pairing), demo_track, path, m, block, run)


def test_replay_no_fit_of_a_session_prints_the_same(real, configs, tmp_path, monkeypatch):
    """``station replay SESSION --no-fit --events``: the same lines, summary, warnings and
    events file read in bulk as read record by record (a session of a real day with a
    damaged record and a torn last one)."""
    from station.cli.main import main as station

    cfg = configs("alge", ALGE_2)
    framer = LineFramer()
    lines = framer.feed((real / "alge/ALGETdC8001-202002020841.dump").read_bytes())
    session = tmp_path / "session"
    session.mkdir()
    (session / "config.yaml").write_text(Path(cfg.path).read_text())
    write_session(session / "raw.jsonl", session_chunks(lines, 3))
    data = (session / "raw.jsonl").read_bytes()
    k = data.index(b"\n", len(data) // 2) + 5
    (session / "raw.jsonl").write_bytes(data[:k] + b"\xff" + data[k + 1 :] + b'{"t":1,"rx"')

    def careful(path, warnings=None):
        yield from read_rawlog(path, warnings)

    outputs = []
    for bulk in (True, False):
        events = tmp_path / f"events-{bulk}.csv"
        out, err = io.StringIO(), io.StringIO()
        with monkeypatch.context() as m:
            if not bulk:
                m.setattr(replay_mod, "read_rawlog_bulk", careful)
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                status = station(["replay", str(session), "--config", cfg.path, "--no-fit",
                                  "--events", str(events)])  # fmt: skip
        assert status == 0, err.getvalue()
        outputs.append((out.getvalue(), err.getvalue(), events.read_text()))
    assert outputs[0] == outputs[1]
    assert "descent 1 " in outputs[0][0] and "torn last record" in outputs[0][1]
    assert "not a raw-log record" in outputs[0][1]
