"""The assembler's batch (``DescentAssembler.feed_run``, which the processor hands a plain
capture's chunk to) decides as the general path, impulse by impulse: the same event for every
impulse and edit, the same descents out of every chunk, the same descents, counts, start dates
and flags at the end, and the same ``station replay --no-fit`` output. On the real captures
(ALGE TdC 8001 days with clears, edits and bibs; the classement print-out; TAG CP540 with its
memory download), on simulated days (overlapping skiers, counters and bibs, double triggers,
missed photocells, running-time lines, midnight) and on those days mutated at random
(hypothesis: lines deleted, repeated, swapped, their flag, channel, bib or time changed,
garbage between them). Three ways are compared: as shipped (the batch), without the batch
(the per-impulse fast paths of today), and the general path alone (every fast path of the
parser and the assembler off)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import random
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from station.model.physics import Conditions, Params, StraightRun
from station.session.config import load_config
from station.session.processor import Processor
from station.session.rawlog import Chunk
from station.timing.assembly import DescentAssembler
from station.timing.framing import LineFramer
from station.timing.impulses import DAY_US, format_tod
from station.timing.wireformats import AlgeParser, format_alge, tag_cs16
from tests.timing_helpers import write_config

WAYS = ("batch", "no batch", "general")
ALGE_2 = {"C0": "PC1", "C1": "PC9"}  # the real ALGE days: start and finish


def _no_run(_self, _items, start, _line):
    return start, [], []


@contextlib.contextmanager
def way(name: str):
    """The processor and assembler as shipped, without the batch, or the general path only."""
    with pytest.MonkeyPatch.context() as m:
        if name != "batch":
            m.setattr(DescentAssembler, "feed_run", _no_run)
        if name == "general":
            m.setattr(DescentAssembler, "_next_photocell", lambda *_a: None)
            m.setattr(DescentAssembler, "_start", lambda *_a: False)
        yield


def _descent(d) -> tuple:
    return dataclasses.astuple(d)


def replayed(cfg, track, data: bytes, cuts: list[int], name: str) -> dict:
    """Everything a replay of ``data`` (cut into chunks at ``cuts``) leaves, as plain values
    taken when they came out: the descents out of each chunk, the events, the end state."""
    with way(name):
        proc = Processor(cfg, track)
        out = []
        at = 0
        for cut in [*cuts, len(data)]:
            out.append([_descent(d) for d in proc.feed(Chunk(None, data[at:cut]))])  # type: ignore[arg-type]
            at = cut
        out.append([_descent(d) for d in proc.finish()])
    asm = proc.assembler
    return {
        "events": [tuple(e) for e in asm.events],
        "per chunk": out,
        "finished": [_descent(d) for d in asm.finished],
        "open": [_descent(d) for d in asm.open],
        "count": asm.count,
        "mode": asm.mode,
        "clock": (asm.clock, asm._day_offset),
        "lines": (proc.lines, proc.impulses, dict(proc.counts), proc.unparsed),
        "starts": [proc.start_host.get(n) for n in range(1, asm.count + 1)],
        "latest start": proc._latest_start,
        "resolution": proc.resolution_us,
    }


def assert_same(a: dict, b: dict, what: str) -> None:
    """Equal, and where not, the first impulse (event) or chunk that differs."""
    for i, (x, y) in enumerate(zip(a["events"], b["events"], strict=False)):
        assert x == y, f"{what}: event {i} (line {x[0]}) differs:\n{x}\n{y}"
    assert len(a["events"]) == len(b["events"]), what
    for i, (x, y) in enumerate(zip(a["per chunk"], b["per chunk"], strict=True)):
        assert x == y, f"{what}: the descents out of chunk {i} differ"
    for key in a:
        assert a[key] == b[key], f"{what}: {key} differs"


def all_ways(cfg, track, data: bytes, cuts: list[int]) -> dict:
    got = {name: replayed(cfg, track, data, cuts, name) for name in WAYS}
    assert_same(got["batch"], got["general"], "batch against the general path")
    assert_same(got["batch"], got["no batch"], "batch against the per-impulse fast paths")
    return got["batch"]


def random_cuts(data: bytes, rng: random.Random, most: int = 700) -> list[int]:
    cuts, at = [], 0
    while True:
        at += rng.randint(1, most)
        if at >= len(data):
            return cuts
        cuts.append(at)


@pytest.fixture(scope="module")
def configs(tmp_path_factory):
    """(protocol, channels, pairing) -> a loaded config on the demo survey."""
    made: dict = {}

    def config(protocol: str = "alge", channels: dict | None = None, pairing: str = "auto"):
        key = (protocol, tuple((channels or {}).items()), pairing)
        if key not in made:
            tmp = tmp_path_factory.mktemp("cfg")
            extra = f"descent: {{pairing: {pairing}}}\n"
            made[key] = load_config(
                str(write_config(tmp, "/dev/null", protocol, channels, extra=extra))
            )
        return made[key]

    return config


# ----------------------------------------------------------------------------- real captures

REAL = [
    ("alge/ALGETdC8001-202002020841.dump", "alge", ALGE_2),
    ("alge/ALGETdC8001-202002021133.dump", "alge", ALGE_2),
    ("alge/ALGETdC8001-202002020841.dump", "alge", None),  # nine photocells: all incomplete
    ("alge/ALGEClassement_Runtime_Run1.txt", "alge", ALGE_2),
    ("tag/cp540_frames.txt", "tag", {"M1": "PC1", "M4": "PC9"}),
]


@pytest.mark.parametrize("pairing", ["auto", "bib", "order"])
@pytest.mark.parametrize(("name", "protocol", "channels"), REAL)
def test_real_captures_the_same_every_way(real, configs, demo_track, name, protocol, channels,
                                          pairing):  # fmt: skip
    data = (real / name).read_bytes()
    if protocol == "tag":  # the frames after the file's comment block, as the timer sent them
        data = b"\r\n".join(
            s for s in data.splitlines() if s.strip() and not s.startswith(b"# ")
        ) + b"\r\n"  # fmt: skip
    cfg = configs(protocol, channels, pairing)
    rng = random.Random(name)
    for cuts in ([], random_cuts(data, rng), random_cuts(data, rng, 40)):
        got = all_ways(cfg, demo_track, data, cuts)
        assert got["lines"][0] > 10  # (the classement print-out has no impulse)


@pytest.fixture
def batch_taken(monkeypatch):
    """How many impulses each call of the assembler's batch took (the batch counted, not
    changed)."""
    taken: list[int] = []
    real_run = DescentAssembler.feed_run

    def counted(self, items, start, line):
        stop, done, started = real_run(self, items, start, line)
        taken.append(stop - start)
        return stop, done, started

    monkeypatch.setattr(DescentAssembler, "feed_run", counted)
    return taken


def clean_day(run_times):
    """50 descents of one skier at a time, a minute apart, every photocell: the batch's case."""
    return [format_alge(f"C{i}", 36_000_000_000 + k * 60_000_000 + int(ti * 1e6), 9 * k + i + 1)
            for k in range(50) for i, ti in enumerate(run_times)]  # fmt: skip


def test_a_clean_day_goes_through_the_batch(configs, demo_track, run_times, batch_taken):
    """Not correct and useless: on a day of one skier at a time every impulse but the first
    (it states the timer's resolution) and the second (it decides the pairing) is taken by the
    batch. (The real ALGE days have two or three skiers on the run at once most of the time:
    the general path's.)"""
    taken = batch_taken
    lines = clean_day(run_times)
    proc = Processor(configs("alge"), demo_track)
    data = ("\r".join(lines) + "\r").encode()
    done = []
    for k in range(0, len(data), 4096):
        done += proc.feed(Chunk(None, data[k : k + 4096]))  # type: ignore[arg-type]
    assert len(done) == 50 and all(d.status == "complete" for d in done)
    assert proc.impulses == 450 and sum(taken) == 448


# ----------------------------------------------------------------------------- simulated days


@pytest.fixture(scope="module")
def run_times(demo_track):
    """The demo run's crossing times (s from the start) of one descent."""
    xs = np.array([pc.x for pc in demo_track.photocells])
    run = StraightRun(demo_track.profile, xs)
    return run.solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079), sensitivities=False).t


def simulated_alge(run_times, seed: int, numbering: str, n: int = 40) -> list[str]:
    """ALGE lines of ``n`` descents over midnight: skiers sometimes on the run together,
    double triggers, missed photocells, a lone start, running-time lines, the timer's memory
    sent again at the end (``m`` lines)."""
    rng = random.Random(seed)
    out: list[tuple[int, str, int]] = []  # (device µs, channel, bib)
    start = 23 * 3600 * 10**6 + 50 * 60 * 10**6
    for k in range(n):
        start += int(rng.uniform(8, 40) * 1e6)  # sometimes before the skier before finished
        scale = rng.uniform(0.85, 1.2)
        bib = k % 60 + 1
        for i, ti in enumerate(run_times):
            if 0 < i < len(run_times) - 1 and rng.random() < 0.04:
                continue  # a missed photocell
            t = start + int(ti * scale * 1e6 + rng.gauss(0, 300))
            out.append((t, f"C{i}", bib))
            if rng.random() < 0.04:  # a double trigger (poles, legs)
                out.append((t + rng.randint(1_000, 200_000), f"C{i}", bib))
        if rng.random() < 0.04:  # someone walking through the start beam
            out.append((start - 3_000_000, "C0", 0))
    out.sort()
    lines = []
    for counter, (t, ch, bib) in enumerate(out, start=1):
        number = bib if numbering == "bib" else counter
        if rng.random() < 0.05:
            lines.append(format_tod((t - 500_000) % DAY_US, 1))  # a running-time line
        lines.append(format_alge(ch, t % DAY_US, number))
    lines += ["m" + s[1:] for s in lines[-12:] if s[0] == " "]  # repeats from the memory
    return lines


def simulated_tag(run_times, seed: int) -> list[str]:
    """TAG time messages by bib without the day counter (the batch's case for TAG)."""
    rng = random.Random(seed)
    lines = []
    start = 10 * 3600 * 10**6
    for k in range(30):
        start += int(rng.uniform(20, 40) * 1e6)
        for i, ti in enumerate(run_times):
            tod = _frac5(start + int(ti * 1e6))
            data = f"TN {k + 1:>4} {len(lines) + 1:>4} {'M' + str(i):>2} {tod}"
            lines.append(f"{data}\t{tag_cs16(data)}")
    return lines


def _frac5(t: int) -> str:
    s = format_tod(t % DAY_US, 5)
    return " " + s[1:] if s[0] == "0" else s


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize(("numbering", "pairing"),
                         [("bib", "auto"), ("counter", "auto"), ("bib", "bib"),
                          ("counter", "order")])  # fmt: skip
def test_simulated_days_the_same_every_way(configs, demo_track, run_times, seed, numbering,
                                           pairing):  # fmt: skip
    lines = simulated_alge(run_times, seed, numbering)
    data = ("\r".join(lines) + "\r").encode("latin-1")
    cfg = configs("alge", None, pairing)
    got = all_ways(cfg, demo_track, data, random_cuts(data, random.Random(seed)))
    assert sum(d[3] == "complete" for d in got["finished"]) > 20  # assembled, not rejected


@pytest.mark.parametrize("pairing", ["auto", "bib"])
def test_a_simulated_tag_day_the_same_every_way(configs, demo_track, run_times, pairing):
    lines = simulated_tag(run_times, 3)
    data = ("\r\n".join(lines) + "\r\n").encode("latin-1")
    channels = {f"M{i}": f"PC{i + 1}" for i in range(9)}
    got = all_ways(configs("tag", channels, pairing), demo_track, data, [])
    assert sum(d[3] == "complete" for d in got["finished"]) == 30


# ----------------------------------------------------------------------------- the edge cases


def _clean(run_times, k: int, start_s: float, numbering: str) -> list[tuple]:
    """Descent k (from 0) of one skier at a time: (channel, s, number, flag) at each photocell."""
    return [(f"C{i}", start_s + ti, k + 1 if numbering == "bib" else 9 * k + i + 1, " ")
            for i, ti in enumerate(run_times)]  # fmt: skip


def _case(run_times, name: str) -> tuple[list[tuple], str, dict | None]:
    """A stream where the batch must stop and leave an impulse to the general path, for each
    condition the batch checks (that the general path decides otherwise there): its impulses,
    the pairing, the channels (None: the nine photocells)."""
    t0 = 36_000.0
    first = _clean(run_times, 0, t0, "bib")  # decides the pairing (the general path)
    if name == "damaged flag":
        second = _clean(run_times, 1, t0 + 60, "bib")
        second[4] = (*second[4][:3], "!")
        return first + second, "bib", None
    if name == "finish within the debounce of the one before":
        run = run_times[-1]
        two = [("C0", t0 + 60, 2, " "), ("C0", t0 + 65, 3, " "), ("C1", t0 + 60 + run, 2, " "),
               ("C1", t0 + 60 + run + 0.1, 3, " ")]  # fmt: skip
        return [("C0", t0, 1, " "), ("C1", t0 + run, 1, " "), *two], "bib", ALGE_2
    if name == "a start repeated":
        second = _clean(run_times, 1, t0 + 60, "bib")
        return first + second + second[:1] + _clean(run_times, 2, t0 + 120, "bib"), "bib", None
    if name == "too slow after the speed before":
        first = _clean(run_times, 0, t0, "counter")
        second = _clean(run_times, 1, t0 + 60, "counter")
        slow = 3 * (second[4][1] - second[3][1])
        second = second[:4] + [(c, s + slow, n, f) for c, s, n, f in second[4:]]
        return first + second, "order", None
    if name == "after the time-out":
        second = _clean(run_times, 1, t0 + 200, "bib")
        late = 87.0 - (second[2][1] - second[1][1])  # 86.6 s time-out, 87.4 s clock jump
        second = second[:2] + [(c, s + late, n, f) for c, s, n, f in second[2:]]
        return first + second, "bib", None
    if name == "a bib of another descent":
        second = _clean(run_times, 1, t0 + 60, "bib")
        second[3] = (second[3][0], second[3][1], 7, " ")
        return first + second, "bib", None
    if name == "without a number":
        second = _clean(run_times, 1, t0 + 60, "bib")
        second[3] = (*second[3][:3], "?")
        return first + second, "bib", None
    raise AssertionError(name)


@pytest.mark.parametrize("name", ["damaged flag", "finish within the debounce of the one before",
                                  "a start repeated", "too slow after the speed before",
                                  "after the time-out", "a bib of another descent",
                                  "without a number"])  # fmt: skip
def test_the_batch_leaves_each_edge_to_the_general_path(configs, demo_track, run_times, name):
    """Each condition of the batch's, met where the general path decides otherwise (a flag on
    the descent, a double trigger collapsed, a repeat not doubled, an impulse rejected): the
    same every way, and that impulse's event is not a plain kept one."""
    stream, pairing, channels = _case(run_times, name)
    lines = [format_alge(c, round(s * 1e6) % DAY_US, n, f) for c, s, n, f in stream]
    data = ("\r".join(lines) + "\r").encode()
    got = all_ways(configs("alge", channels, pairing), demo_track, data, [])
    plain = [e for e in got["events"] if e[5] and not e[6]]
    flagged = [d for d in got["finished"] if d[4]]
    assert len(plain) < len(stream) or flagged, "the case is no edge: the general path agrees"


def test_over_midnight_in_the_batch(configs, demo_track, run_times):
    """A day of one skier at a time over midnight, in one chunk: the batch moves the clock's
    day as the general path does (a later time of day unwraps on it)."""
    stream = [x for k in range(12) for x in _clean(run_times, k, 86_100 + 30 * k, "counter")]
    lines = [format_alge(c, round(s * 1e6) % DAY_US, n, f) for c, s, n, f in stream]
    data = ("\r".join(lines) + "\r").encode()
    got = all_ways(configs("alge", None, "order"), demo_track, data, [])
    assert got["clock"][1] == 1 and len(got["finished"]) == 12
    # the chunk ends within a descent just past midnight; the next begins with a time from
    # before midnight at a later photocell (the general path's): unwrapped on the clock's day
    descent = _clean(run_times, 0, 86_395, "counter")
    stray = ("C5", 86_398, 99, " ")
    lines = [format_alge(c, round(s * 1e6) % DAY_US, n, f)
             for c, s, n, f in [*descent[:4], stray, *descent[4:]]]  # fmt: skip
    data = ("\r".join(lines) + "\r").encode()
    got = all_ways(configs("alge", None, "order"), demo_track, data, [4 * 27])
    assert got["clock"][1] == 1 and len(got["finished"]) == 1


# ----------------------------------------------------------------------------- mutated days

FLAGS = " ?cimdC!x"
#: time shifts (µs): a double trigger, a slower or faster section, past a time-out, a flipped
#: hour digit, a day back
SHIFTS = [1, 250_000, -1_200_000, -2_000_000, 3_500_000, 30_000_000, 87_000_000,
          3 * 3600 * 10**6, -(10**10)]  # fmt: skip


def mutate(lines: list[str], ops: list[tuple[int, int, int]]) -> list[str]:
    """``lines`` with each (what, where, how much) applied in turn."""
    lines = list(lines)
    for what, where, much in ops:
        if not lines:
            break
        i = where % len(lines)
        s = lines[i]
        if what == 0:
            del lines[i]
        elif what == 1:
            lines.insert(min(len(lines), i + 1 + much % 40), s)  # a repeat, later
        elif what == 2 and i + 1 < len(lines):
            lines[i], lines[i + 1] = lines[i + 1], s  # out of order
        elif len(s) != 26:
            lines.insert(i, "".join(chr(32 + (much * 7 + k) % 90) for k in range(much % 30)))
        elif what == 3:
            lines[i] = FLAGS[much % len(FLAGS)] + s[1:]  # an edit, a repeat, a damaged byte
        elif what == 4:
            lines[i] = s[:6] + f"C{much % 10} " + s[9:]  # another photocell (or none)
        elif what == 5:
            lines[i] = s[:1] + f"{much % 10000:04d}" + s[5:]  # another number
        elif what == 6:
            t = AlgeParser().parse(s)
            tod = getattr(t, "tod_us", None)
            if tod is not None:  # small shifts and big jumps (a flipped hour digit)
                shift = SHIFTS[much % len(SHIFTS)]
                lines[i] = s[:10] + format_tod((tod + shift) % DAY_US, 4) + s[23:]
        else:
            lines.insert(i, "CLASSEMENT:" if much % 9 == 0 else "garbage " + str(much))
    return lines


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(
    seed=st.integers(0, 10_000),
    numbering=st.sampled_from(["bib", "counter"]),
    pairing=st.sampled_from(["auto", "bib", "order"]),
    ops=st.lists(
        st.tuples(st.integers(0, 7), st.integers(0, 10**6), st.integers(0, 10**6)), max_size=40
    ),  # fmt: skip
    chunk=st.integers(1, 2000),
)
def test_mutated_days_the_same_every_way(configs, demo_track, run_times, seed, numbering,
                                         pairing, ops, chunk):  # fmt: skip
    lines = mutate(simulated_alge(run_times, seed, numbering, n=15), ops)
    data = ("\r".join(lines) + "\r").encode("latin-1")
    all_ways(configs("alge", None, pairing), demo_track, data,
             list(range(chunk, len(data), chunk)))  # fmt: skip


# ----------------------------------------------------------------------------- sessions


def session_chunks(lines: list[str], seed: int) -> list[Chunk]:
    """A session's raw log of ``lines``: a record a line, as a recording reads them, at host
    times that follow the timer's clock (a line whose time does not read, or is far off, comes
    0.3 s after the one before); now and then two lines in one read, a line split over two
    reads, a time-out event, a disconnect."""
    rng = random.Random(seed)
    parser = AlgeParser()
    chunks: list[Chunk] = []
    host = 1_767_600_000.0
    for line in lines:
        tod = getattr(parser.parse(line), "tod_us", None)
        guess = 1_767_600_000.0 + (tod or 0) / 1e6 + rng.uniform(0, 0.05)
        while guess < host - 43_200:
            guess += 86_400
        host = guess if tod is not None and abs(guess - host) < 60 else host + 0.3
        data = (line + "\r").encode("latin-1")
        roll = rng.random()
        if roll < 0.03 and chunks and chunks[-1].data:  # two lines in one read
            chunks[-1] = Chunk(chunks[-1].t, chunks[-1].data + data)
        elif roll < 0.06:  # a line over two reads
            chunks += [Chunk(host, data[:10]), Chunk(host + 0.001, data[10:])]
        else:
            chunks.append(Chunk(host, data))
        if rng.random() < 0.03:
            chunks.append(Chunk(host + rng.uniform(0, 120), b"", "timeout"))
        if rng.random() < 0.005:
            chunks.append(Chunk(host + 0.5, b"", "disconnected", "EIO"))
    return chunks


def replayed_session(cfg, track, chunks: list[Chunk], name: str) -> dict:
    """A session's chunks replayed as ``replay --no-fit`` does (``feed_chunks``, the batch)
    or a chunk at a time (``feed``, as a recording and a replay with fits do)."""
    with way(name):
        proc = Processor(cfg, track)
        if name == "batch":
            out = proc.feed_chunks(chunks)
        else:
            out = [d for chunk in chunks for d in proc.feed(chunk)]
        out += proc.finish()
    asm = proc.assembler
    return {
        "events": [tuple(e) for e in asm.events],
        "per chunk": [[d.number for d in out]],  # (an edit changes a descent after it came out)
        "finished": [_descent(d) for d in asm.finished],
        "open": [_descent(d) for d in asm.open],
        "count": asm.count,
        "mode": asm.mode,
        "clock": (asm.clock, asm._day_offset),
        "lines": (proc.lines, proc.impulses, dict(proc.counts), proc.unparsed),
        "starts": [proc.start_host.get(n) for n in range(1, asm.count + 1)],
        "latest start": proc._latest_start,
        "resolution": proc.resolution_us,
        "host": (proc.offset_us, list(proc._recent), proc._chunk_t, proc.connection),
    }


def all_ways_session(cfg, track, chunks: list[Chunk]) -> dict:
    got = {name: replayed_session(cfg, track, chunks, name) for name in WAYS}
    assert_same(got["batch"], got["general"], "session: batch against the general path")
    assert_same(got["batch"], got["no batch"], "session: batch against chunk by chunk")
    return got["batch"]


@pytest.mark.parametrize("pairing", ["auto", "bib"])
@pytest.mark.parametrize("name", ["ALGETdC8001-202002020841.dump", "ALGETdC8001-202002021133.dump"])
def test_real_days_as_sessions_the_same_every_way(real, configs, demo_track, name, pairing):
    framer = LineFramer()
    lines = framer.feed((real / "alge" / name).read_bytes()) + framer.flush()
    for seed in range(3):
        got = all_ways_session(configs("alge", ALGE_2, pairing), demo_track,
                               session_chunks(lines, seed))  # fmt: skip
        assert got["starts"] and all(h is not None for h in got["starts"][:50])


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(("numbering", "pairing"), [("bib", "auto"), ("counter", "auto")])
def test_simulated_sessions_the_same_every_way(configs, demo_track, run_times, seed, numbering,
                                               pairing):  # fmt: skip
    lines = simulated_alge(run_times, seed, numbering)
    got = all_ways_session(configs("alge", None, pairing), demo_track,
                           session_chunks(lines, seed))  # fmt: skip
    assert sum(d[3] == "complete" for d in got["finished"]) > 20


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("numbering", ["bib", "counter"])
def test_sessions_with_the_memory_from_mid_descent_the_same_every_way(
    configs, demo_track, run_times, seed, numbering
):
    """An ``import`` event mid-day (what follows is the timer's memory): the batch and the
    per-impulse fast paths start its descents as from the memory, and leave an impulse of it
    that continues a descent recorded live to the general path, which flags the join."""
    lines = simulated_alge(run_times, seed, numbering)
    chunks = [c for c in session_chunks(lines, seed) if c.event != "disconnected"]
    # after a PC4 crossing a third into the day: a descent is open, the memory continues it
    at = next(i for i in range(len(chunks) // 3, len(chunks)) if b" C3 " in chunks[i].data) + 1
    chunks.insert(at, Chunk(chunks[at].t, b"", "import", "imports/download.txt"))
    got = all_ways_session(configs("alge", None, "auto"), demo_track, chunks)
    assert sum(d[3] == "complete" for d in got["finished"]) > 20
    joins = sum(f.startswith("joined: ") for d in got["finished"] for f in d[4])
    assert joins >= 1  # (and those the stream's time-outs ended short, reopened)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(
    seed=st.integers(0, 10_000),
    numbering=st.sampled_from(["bib", "counter"]),
    pairing=st.sampled_from(["auto", "bib", "order"]),
    ops=st.lists(
        st.tuples(st.integers(0, 7), st.integers(0, 10**6), st.integers(0, 10**6)), max_size=40
    ),
)
def test_mutated_sessions_the_same_every_way(configs, demo_track, run_times, seed, numbering,
                                             pairing, ops):  # fmt: skip
    lines = mutate(simulated_alge(run_times, seed, numbering, n=15), ops)
    all_ways_session(configs("alge", None, pairing), demo_track, session_chunks(lines, seed))


def test_a_clean_session_goes_through_the_batch(configs, demo_track, run_times, batch_taken):
    taken = batch_taken
    lines = clean_day(run_times)
    host = 1_767_600_000.0
    chunks = [Chunk(host + 36_000 + k * 60 + ti + 0.01, (line + "\r").encode())
              for line, (k, ti) in zip(lines, [(k, ti) for k in range(50) for ti in run_times],
                                       strict=True)]  # fmt: skip
    proc = Processor(configs("alge"), demo_track)
    done = proc.feed_chunks(chunks)
    assert len(done) == 50 and all(d.status == "complete" for d in done)
    assert proc.impulses == 450 and sum(taken) == 448
    assert proc.start_host.get(50) == chunks[49 * 9].t


# ----------------------------------------------------------------------------- the command


def test_replay_no_fit_prints_the_same_every_way(real, configs, tmp_path):
    """``station replay CAPTURE --no-fit --events``: the same lines, summary and events file."""
    from station.cli.main import main as station

    cfg = configs("alge", ALGE_2)
    capture = Path(real / "alge/ALGETdC8001-202002020841.dump")
    outputs = []
    for name in WAYS:
        events = tmp_path / f"events-{name.replace(' ', '-')}.csv"
        out, err = io.StringIO(), io.StringIO()
        with way(name), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = station(["replay", str(capture), "--config", cfg.path, "--no-fit",
                              "--date", "2020-02-02", "--events", str(events)])  # fmt: skip
        assert status == 0, err.getvalue()
        outputs.append((out.getvalue(), err.getvalue(), events.read_text()))
    assert outputs[0] == outputs[1] == outputs[2]
    assert "descent 1 " in outputs[0][0] and "cleared" in outputs[0][2]
