"""``station-sim``: a simulated sports timer on a pseudo-terminal.

It opens a pty (``os.openpty``), prints ``PORT <path>`` as its first line, and speaks the chosen
protocol (ALGE, TAG Heuer THCOM08, Microgate Racetime2) on it byte for byte like the hardware.
The descents come from the physics of :mod:`station.model.physics` on a survey's track: skier
parameters fixed or drawn per descent (seeded), timing noise, and field quirks (double
triggers, missed photocells, walk-throughs, running-time lines, garbage bytes, a disconnect).

``<path>`` is a symlink to the pty's slave. On a simulated disconnect the pty is closed and a
new one is opened behind the same symlink, the way a USB-serial adapter comes back under the
same device name. With ``--truth FILE`` every descent's true parameters and crossing times
are written there as JSON lines, for tests.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import json
import os
import signal
import sys
import tempfile
import time
import tty

import numpy as np

from station.model.physics import Conditions, Params, StraightRun
from station.survey.load import load_survey
from station.survey.track import build_track
from station.timing.impulses import format_tod
from station.timing.wireformats import format_alge, format_racetime, format_tag

DEFAULT_SURVEY = os.path.join(
    os.path.dirname(os.path.dirname(__file__)), "surveys", "demo_run.yaml"
)
LINE_END = {"alge": b"\r", "tag": b"\r\n", "microgate": b"\r"}


def default_channels(protocol: str, n: int) -> list[str]:
    """Channel names of n photocells in order down the run, as a timer would wire them."""
    if protocol == "alge":
        if n > 10:
            raise ValueError("an ALGE timer has channels C0..C9: at most 10 photocells")
        return [f"C{i}" for i in range(n)]
    if protocol == "tag":
        return [str(i + 1) for i in range(n)]
    return ["000"] + [f"{i:03d}" for i in range(1, n - 1)] + ["255"]


class PtyPort:
    """A pty behind a stable symlink; can be 'unplugged' and 'plugged in' again."""

    def __init__(self, link: str | None = None) -> None:
        self.link = link or os.path.join(tempfile.mkdtemp(prefix="station-sim-"), "timer")
        self.master = -1
        self.slave = -1
        self.plug()

    def plug(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no CR->LF translation, no echo, before anyone opens it
        tmp = self.link + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(os.ttyname(self.slave), tmp)
        os.replace(tmp, self.link)

    def unplug(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        self.master = self.slave = -1

    def write(self, data: bytes) -> None:
        if self.master >= 0:
            os.write(self.master, data)

    def close(self) -> None:
        self.unplug()
        if os.path.lexists(self.link):
            os.unlink(self.link)


class Timer:
    """The device clock, the protocol and the quirks."""

    def __init__(self, args: argparse.Namespace, port: PtyPort) -> None:
        self.args = args
        self.port = port
        self.rng = np.random.default_rng(args.seed)
        self.counter = 0
        now = dt.datetime.now()
        midnight = now.replace(hour=0, minute=0, second=0, microsecond=0)
        self.tod0_us = int((now - midnight).total_seconds() * 1e6)
        if args.start_tod:
            h, m, s = (float(v) for v in args.start_tod.split(":"))
            self.tod0_us = int(((h * 60 + m) * 60 + s) * 1e6)
        self.day = (now.date() - dt.date(2000, 1, 1)).days
        self.m0 = time.monotonic()

    def tod_us(self) -> int:
        """Device time of day now: runs ``speed`` times faster than the wall clock."""
        return self.tod0_us + int((time.monotonic() - self.m0) * self.args.speed * 1e6)

    def wait_until(self, tod_us: int) -> None:
        while True:
            delay = (tod_us - self.tod_us()) / 1e6 / self.args.speed
            if delay <= 0:
                return
            time.sleep(min(delay, 0.05))

    def line(self, channel: str, tod_us: int) -> bytes:
        self.counter += 1
        p = self.args.protocol
        tod_us %= 86_400_000_000
        if p == "alge":
            text = format_alge(channel, tod_us, self.counter, checksum=self.args.checksum)
        elif p == "tag":
            text = format_tag(channel, tod_us, self.counter, "", self.day)
        else:
            text = format_racetime(channel, tod_us, self.counter)
        return text.encode("ascii") + LINE_END[p]

    def send(self, data: bytes) -> None:
        self.port.write(data)


def run(args: argparse.Namespace) -> int:
    track = build_track(load_survey(args.survey))
    ids = track.photocell_ids
    channels = (
        args.channels.split(",") if args.channels else default_channels(args.protocol, len(ids))
    )
    if len(channels) != len(ids):
        print(
            f"station-sim: error: {len(channels)} channels for {len(ids)} photocells",
            file=sys.stderr,
        )
        return 2
    xs = np.array([pc.x for pc in track.photocells])
    sim = StraightRun(track.profile, xs)
    port = PtyPort(args.link)
    print(f"PORT {port.link}", flush=True)
    timer = Timer(args, port)
    truth = open(args.truth, "a", encoding="utf-8") if args.truth else None  # noqa: SIM115
    stop = {"now": False}

    def on_signal(*_):
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    rng = timer.rng
    skis = [float(v) for v in args.skis.split(",")] if args.skis else []
    next_start = timer.tod_us() + int(args.first_after * args.speed * 1e6)
    next_start = -(-next_start // 1_000_000) * 1_000_000  # whole seconds: reproducible
    prev_end: int | None = None
    first_start = next_start
    last_running = timer.tod_us() // 1_000_000 * 1_000_000
    try:
        for k in range(args.descents):
            if stop["now"]:
                break
            drift = args.mu_drift_per_hour * (next_start - first_start) / 3.6e9
            if skis and args.order:
                # a test design: pairs in the given order, one tuck (CdA) for the skier, the
                # track drifting; only v0 varies from descent to descent
                pair = ord(args.order[k % len(args.order)].upper()) - ord("A")
                p = Params(cda=args.cda, mu=skis[pair] + drift, v0=float(rng.uniform(2.5, 4.5)))
            elif skis:
                # pairs of skis in rotation, each with its own friction; the skier varies a little
                p = Params(
                    cda=float(rng.normal(0.22, 0.01)),
                    mu=skis[k % len(skis)] * float(rng.normal(1.0, 0.03)) + drift,
                    v0=float(rng.uniform(2.5, 4.5)),
                )
            elif args.vary:
                p = Params(
                    cda=float(rng.uniform(0.18, 0.30)),
                    mu=float(rng.uniform(0.006, 0.030)),
                    v0=float(rng.uniform(2.0, 6.0)),
                )
            else:
                p = Params(args.cda, args.mu, args.v0, args.mu1)
            d = sim.solve(p, Conditions(args.mass, args.air_density), sensitivities=False)
            if d.stopped_x is not None:
                print(f"station-sim: descent {k + 1} would stop; skipped", file=sys.stderr)
                continue
            t = d.t + np.concatenate([[0.0], rng.normal(0.0, args.noise_ms * 1e-3, len(d.t) - 1)])
            start = -(-next_start // 1_000_000) * 1_000_000  # on a whole second: reproducible
            events: list[tuple[int, str, str]] = []  # (tod, channel, kind)
            sent_ids = []
            for i, (ch, ti) in enumerate(zip(channels, t, strict=True)):
                if 0 < i < len(ids) - 1 and rng.random() < args.miss:
                    continue
                tod = start + int(round(ti * 1e6))
                events.append((tod, ch, "impulse"))
                sent_ids.append(ids[i])
                if rng.random() < args.double_trigger:
                    events.append((tod + int(rng.uniform(0.02, 0.15) * 1e6), ch, "double"))
            if args.walkthrough and rng.random() < args.walkthrough and prev_end is not None:
                # someone walks through the start beam between two descents
                events.insert(0, ((prev_end + start) // 2, channels[0], "walkthrough"))
            events.sort()
            prev_end = events[-1][0]
            for tod, ch, _kind in events:
                if args.running_time and args.protocol == "alge":
                    # running-time lines at every full second of the device clock (ALGE EMU1)
                    while last_running + 1_000_000 < tod and not stop["now"]:
                        last_running += 1_000_000
                        timer.wait_until(last_running)
                        timer.send(format_tod(last_running, 1).encode() + b"\r")
                timer.wait_until(tod)
                if args.garbage and rng.random() < args.garbage:
                    junk = bytes(rng.integers(0, 256, int(rng.integers(3, 20)), dtype=np.uint8))
                    timer.send(junk.replace(b"\r", b"").replace(b"\n", b"") + b"\r")
                timer.send(timer.line(ch, tod))
            if truth is not None:
                truth.write(
                    json.dumps(
                        {
                            "descent": k + 1,
                            "cda": p.cda,
                            "mu": p.mu,
                            "v0": p.v0,
                            "mu1": p.mu1,
                            "pair": args.order[k % len(args.order)] if args.order else None,
                            "start_tod_us": start,
                            "photocells": sent_ids,
                            "t": [float(x) for x in t],
                        }
                    )
                    + "\n"
                )
                truth.flush()
            if args.disconnect_after and k + 1 == args.disconnect_after:
                port.unplug()
                print(f"station-sim: unplugged after descent {k + 1}", file=sys.stderr, flush=True)
                time.sleep(args.disconnect_s)
                port.plug()
                print("station-sim: plugged in again", file=sys.stderr, flush=True)
            next_start = max(start + int(args.interval * 1e6), timer.tod_us() + 1_000_000)
        # leave the port open a moment so the last bytes are read, unless told to hold it
        end = time.monotonic() + args.hold
        while time.monotonic() < end and not stop["now"]:
            time.sleep(0.05)
    finally:
        if truth is not None:
            truth.close()
        port.close()
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="station-sim", description=__doc__.splitlines()[0])
    ap.add_argument("--survey", default=DEFAULT_SURVEY, help="survey YAML (default: the demo run)")
    ap.add_argument("--protocol", choices=["alge", "tag", "microgate"], default="alge")
    ap.add_argument("--channels", help="comma-separated channel names down the run")
    ap.add_argument("--checksum", action="store_true", help="ALGE CHK1 checksums")
    ap.add_argument("--descents", type=int, default=10)
    ap.add_argument("--interval", type=float, default=20.0, help="seconds between starts")
    ap.add_argument(
        "--first-after", type=float, default=3.0, help="wall-clock seconds to the first start"
    )
    ap.add_argument("--speed", type=float, default=1.0, help="device clock runs this much faster")
    ap.add_argument("--start-tod", help="device time of day at start, HH:MM:SS (default: now)")
    ap.add_argument("--mass", type=float, default=88.0)
    ap.add_argument("--air-density", type=float, default=1.079)
    ap.add_argument("--cda", type=float, default=0.22)
    ap.add_argument("--mu", type=float, default=0.0085)
    ap.add_argument("--mu1", type=float, default=0.0)
    ap.add_argument("--v0", type=float, default=3.4)
    ap.add_argument("--vary", action="store_true", help="draw CdA, μ, v0 per descent")
    ap.add_argument("--skis", help="μ of ski pairs used in rotation, e.g. 0.008,0.0095,0.011")
    ap.add_argument("--order", help="pairs of --skis in this order, e.g. ABBAABBA (fixed CdA)")
    ap.add_argument("--mu-drift-per-hour", type=float, default=0.0, help="μ drift of the track")
    ap.add_argument("--noise-ms", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--double-trigger", type=float, default=0.0, metavar="P")
    ap.add_argument("--miss", type=float, default=0.0, metavar="P", help="miss a middle photocell")
    ap.add_argument(
        "--walkthrough", type=float, default=0.0, metavar="P", help="lone start impulses"
    )
    ap.add_argument("--running-time", action="store_true", help="ALGE running-time lines")
    ap.add_argument(
        "--garbage", type=float, default=0.0, metavar="P", help="garbage bytes per line"
    )
    ap.add_argument("--disconnect-after", type=int, default=0, metavar="K")
    ap.add_argument("--disconnect-s", type=float, default=2.0)
    ap.add_argument(
        "--hold", type=float, default=2.0, help="seconds to keep the port after the end"
    )
    ap.add_argument("--link", help="path of the symlink to the pty (default: a temp dir)")
    ap.add_argument("--truth", help="append each descent's truth as JSON lines to this file")
    return ap


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
