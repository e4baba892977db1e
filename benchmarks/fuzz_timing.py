"""Fuzz the timing path: mixed and bit-flipped captures through the processor (issue 9).

Replays, through the same :class:`Processor` that records and replays a day:

- clean days written by the formatters (ALGE with and without CHK1 checksums, TAG THCOM08,
  Microgate Racetime2), with garbage lines, status lines and print-outs mixed in;
- the two real ALGE TdC 8001 race captures (../shared/fixtures/real/alge);
- the same captures with single bits flipped in about 1 % of their lines.

It reports crashes (an exception out of the processor: must be 0) and the valid impulses lost:
an impulse that is in a descent on the clean capture and in none on the flipped one. A lost
impulse is counted as

- *own line*: its own bytes were damaged;
- *start lost*: intact, but its descent's start impulse was damaged. The Processor tells the
  assembler of a line it could not read, and a later photocell then starts the descent (flagged
  "start line damaged"); what is still lost here is where the damaged start was read as
  something else (an impulse at another channel, a skipped line) or, on a start/finish
  course, a finish alone (nothing to fit);
- *other line*: intact, its start intact, but another line of its descent was damaged (an
  operator's edit line, or a damaged impulse that took its place);
- *unexplained*: nothing of its descent was damaged. Must be 0; each one is listed.

    python benchmarks/fuzz_timing.py [--seed N] [--flipped-runs N]

Runs in well under two minutes on one core.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station.session.config import load_config  # noqa: E402
from station.session.processor import Processor  # noqa: E402
from station.session.rawlog import Chunk  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402
from station.timing.impulses import DAY_US, Edit, Impulse  # noqa: E402
from station.timing.wireformats import (  # noqa: E402
    format_alge,
    format_racetime,
    format_tag,
    make_parser,
)

REAL = Path(os.environ.get("STATION_REAL_FIXTURES", ROOT.parent / "shared/fixtures/real"))
END = {"alge": b"\r", "tag": b"\r\n", "microgate": b"\r"}
NOISE = ["TIMY: 480170000", "n0007", "CLR", "PROG: PC-TIMER", "10:15:13.2", "AK C\t00EF",
         "SN 04811 CP545 VB10", "\x02R2        ", " 0001 RT  00:00:59.76   00"]  # fmt: skip
PRINTOUT = ["CLASSEMENT:", "ALL", "RUN TIME", " 0001 RTM 00:00:13.39   00 0001", "  ALGE TIMING",
            "   TdC  8001", "  DEU V 18.92", "21-11-28  17:04"]  # fmt: skip


def channels_for(protocol: str) -> list[str]:
    if protocol == "alge":
        return [f"C{i}" for i in range(9)]
    if protocol == "tag":
        return [str(i + 1) for i in range(9)]
    return ["000"] + [f"{i:03d}" for i in range(1, 8)] + ["255"]


def processor_for(base, track, protocol: str, channels: dict[str, str]) -> Processor:
    serial = dataclasses.replace(base.serial, protocol=protocol)
    return Processor(dataclasses.replace(base, serial=serial, channels=channels), track)


def synthetic_day(protocol: str, positions: list[float], n: int, rng, checksum=False) -> bytes:
    """n descents 30 s apart (two skiers on the run at times), noise lines in between."""
    chans = channels_for(protocol)
    events = []
    for k in range(n):
        t0 = 9 * 3600.0 + 30.0 * k
        v0, a = rng.uniform(3, 5), rng.uniform(0.3, 0.6)
        for ch, x in zip(chans, positions, strict=True):
            v = np.sqrt(v0**2 + 2 * a * x)
            events.append((t0 + (v - v0) / a, ch, k + 1))
    events.sort()
    out = []
    for i, (t, ch, bib) in enumerate(events):
        tod = round(t * 1e6) % DAY_US
        if protocol == "alge":
            out.append(format_alge(ch, tod, i + 1, checksum=checksum))
        elif protocol == "tag":
            out.append(format_tag(ch, tod, i + 1, bib, 9000))
        else:
            out.append(format_racetime(ch, tod, i + 1, bib))
        r = rng.random()
        if r < 0.05:
            junk = bytes(rng.integers(0, 256, int(rng.integers(1, 40)), dtype=np.uint8))
            out.append(junk.replace(b"\r", b"").replace(b"\n", b"").decode("latin-1"))
        elif r < 0.08:
            out.append(NOISE[int(rng.integers(len(NOISE)))])
        elif r < 0.081 and protocol == "alge":
            out.extend(PRINTOUT)
    return b"".join(s.encode("latin-1") + END[protocol] for s in out)


def split_lines(data: bytes, end: bytes) -> list[bytes]:
    parts = data.split(end)
    return [p + end for p in parts[:-1]] + ([parts[-1]] if parts[-1] else [])


def flip(lines: list[bytes], rng, rate: float) -> tuple[list[bytes], set[int]]:
    """Flip one bit in about ``rate`` of the lines (never in the line end)."""
    out, damaged = list(lines), set()
    for i, s in enumerate(lines):
        body = s.rstrip(b"\r\n")
        if body and rng.random() < rate:
            j = int(rng.integers(len(body)))
            b = bytearray(s)
            b[j] ^= 1 << int(rng.integers(8))
            out[i] = bytes(b)
            damaged.add(i)
    return out, damaged


def identity(parser, line: bytes):
    text = line.rstrip(b"\r\n").decode("latin-1")
    p = parser.parse(text)
    if isinstance(p, (Impulse, Edit)):
        return (p.channel, p.tod_us % DAY_US)
    return None


def membership(proc: Processor) -> dict[tuple[str, int], set[int]]:
    """Impulse or edit identity -> the number of the descent it was in or changed (an impulse
    cleared later still belongs to its descent)."""
    out: dict[tuple[str, int], set[int]] = {}
    for e in proc.events:
        if e.descent is not None:
            out.setdefault((e.channel, e.tod_us), set()).add(e.descent)
    return out


def run(proc: Processor, data: bytes) -> tuple[Counter, int]:
    """Feed a capture in 4 KiB chunks; the impulses in descents at the end, crashes."""
    crashes = 0
    for i in range(0, len(data), 4096):
        try:
            proc.feed(Chunk(None, data[i : i + 4096]))  # type: ignore[arg-type]
        except Exception as exc:  # noqa: BLE001 - counting them is the point
            crashes += 1
            print(f"  CRASH: {type(exc).__name__}: {exc}", file=sys.stderr)
    try:
        proc.finish()
    except Exception as exc:  # noqa: BLE001
        crashes += 1
        print(f"  CRASH at finish: {type(exc).__name__}: {exc}", file=sys.stderr)
    asm = proc.assembler
    kept: Counter = Counter()
    for d in asm.finished + asm.open:
        for ch, t in zip(d.channels, d.times_us, strict=True):
            kept[(ch, t % DAY_US)] += 1
    return kept, crashes


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--flipped-runs", type=int, default=12)
    ap.add_argument("--descents", type=int, default=900)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    base = load_config(str(ROOT / "surveys" / "demo_station.yaml"))
    track = build_track(load_survey(base.survey_path))
    x0 = track.photocells[0].x
    positions = [track.profile.arc_length(x0, pc.x) for pc in track.photocells]
    ids = track.photocell_ids
    cases = []
    for protocol, checksum in (("alge", False), ("alge", True), ("tag", False),
                               ("microgate", False)):  # fmt: skip
        data = synthetic_day(protocol, positions, args.descents, rng, checksum)
        chans = dict(zip(channels_for(protocol), ids, strict=True))
        name = f"{protocol}{' CHK1' if checksum else ''} synthetic"
        cases.append((name, protocol, chans, data))
    for dump in sorted((REAL / "alge").glob("*.dump")):
        data = dump.read_bytes().replace(b"\n", b"\r")
        cases.append((f"real {dump.name}", "alge", {"C0": ids[0], "C1": ids[-1]}, data))

    t_start = time.perf_counter()
    total_lines = total_crashes = total_unexplained = total_lost_damaged = total_with = 0
    total_start = 0
    total_valid = 0
    print(f"{'capture':46s} {'lines':>7s} {'crashes':>7s} {'kept':>6s} {'lost: own line':>14s} "
          f"{'start lost':>10s} {'other line':>10s} {'unexplained':>11s}")  # fmt: skip
    for name, protocol, chans, data in cases:
        end = END[protocol]
        lines = split_lines(data, end)
        clean_proc = processor_for(base, track, protocol, chans)
        baseline, crashes = run(clean_proc, data)
        total_lines += clean_proc.lines
        total_crashes += crashes
        member = membership(clean_proc)
        asm = clean_proc.assembler
        starts = {d.number: (d.channels[0], d.first_us % DAY_US) for d in asm.finished + asm.open
                  if d.channels}  # fmt: skip
        print(
            f"{name + ' (clean)':46s} {clean_proc.lines:7d} {crashes:7d} "
            f"{sum(baseline.values()):6d} {'-':>14s} {'-':>10s} {'-':>10s} {'-':>11s}"
        )
        lost_own = lost_start = lost_with = lost_other = lines_run = crash_run = 0
        runs = args.flipped_runs if name.startswith("real") else max(2, args.flipped_runs // 4)
        for _ in range(runs):
            flipped, damaged = flip(lines, rng, 0.01)
            parser = make_parser(protocol)
            own = Counter()
            for i in damaged:
                ident = identity(parser, lines[i])
                if ident is not None:
                    own[ident] += 1
            proc = processor_for(base, track, protocol, chans)
            kept, crashes = run(proc, b"".join(flipped))
            lines_run += proc.lines
            crash_run += crashes
            lost = baseline - kept
            other = lost - own
            lost_own += sum((lost & own).values())
            hit = set().union(*(member.get(ident, set()) for ident in own))
            start_hit = {n for n in hit if starts.get(n) in own}
            for ident, c in other.items():
                if member.get(ident, set()) & start_hit:
                    lost_start += c
                elif member.get(ident, set()) & hit:
                    lost_with += c
                else:
                    lost_other += c
                    why = [e.reason for e in proc.events
                           if (e.channel, e.tod_us) == ident and not e.kept]  # fmt: skip
                    print(f"  unexplained loss: {ident} x{c}: {why}", file=sys.stderr)
            total_valid += sum(baseline.values())
        total_lines += lines_run
        total_crashes += crash_run
        total_lost_damaged += lost_own
        total_with += lost_with
        total_start += lost_start
        total_unexplained += lost_other
        print(
            f"{name + f' ({runs} x 1% flips)':46s} {lines_run:7d} {crash_run:7d} "
            f"{'':6s} {lost_own:14d} {lost_start:10d} {lost_with:10d} {lost_other:11d}"
        )
    elapsed = time.perf_counter() - t_start
    print()
    print(f"lines replayed: {total_lines}  in {elapsed:.1f} s")
    print(f"crashes: {total_crashes}")
    print(f"valid impulses in the flipped runs' clean baselines: {total_valid}")
    print(f"lost, own line damaged: {total_lost_damaged}")
    print(f"lost with their descent's start (own line intact, the start's line damaged): "
          f"{total_start}")  # fmt: skip
    print(f"lost with another line of their descent damaged (own line and start intact): "
          f"{total_with}")  # fmt: skip
    print(f"lost, unexplained (nothing of their descent damaged): {total_unexplained}")
    return 1 if total_crashes or total_unexplained else 0


if __name__ == "__main__":
    raise SystemExit(main())
