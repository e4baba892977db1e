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
import fcntl
import heapq
import json
import os
import select
import signal
import struct
import sys
import tempfile
import termios
import time
import tty
from typing import TextIO

import numpy as np

from station import __version__
from station.model.physics import StraightRun
from station.simulators.descents import Planned, Planner
from station.survey.load import load_survey
from station.survey.track import build_track
from station.timing.impulses import format_tod
from station.timing.wireformats import format_alge, format_racetime, format_tag, tag_cs16

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
        self.name = os.ttyname(self.slave)
        tmp = self.link + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(self.name, tmp)
        os.replace(tmp, self.link)

    def wait_for_reader(self, timeout_s: float) -> bool:
        """Wait until someone opens the port, so that nothing is written into a queue that the
        reader's open would flush. With no slave open the master reports POLLHUP."""
        os.close(self.slave)
        poll = select.poll()
        poll.register(self.master, select.POLLHUP)
        end = time.monotonic() + timeout_s
        found = False
        while time.monotonic() < end:
            if not any(ev & select.POLLHUP for _fd, ev in poll.poll(50)):
                found = True
                break
        # hold the slave again: it keeps the port alive and lets drain() see the queue
        self.slave = os.open(self.name, os.O_RDWR | os.O_NOCTTY)
        return found

    def drain(self, timeout_s: float = 3.0, settle_s: float = 0.3) -> None:
        """Wait until the reader has taken every byte written (before an 'unplug'). Bytes written
        to the master reach the slave's input queue a moment later, and a reader takes a moment
        to pass on what it read, so the queue must stay empty for ``settle_s``."""
        end = time.monotonic() + timeout_s
        empty_since = None
        while self.slave >= 0 and time.monotonic() < end:
            time.sleep(0.02)
            try:
                pending = struct.unpack("i", fcntl.ioctl(self.slave, termios.FIONREAD, b"\0" * 4))
            except OSError:
                return
            if pending[0]:
                empty_since = None
            elif empty_since is None:
                empty_since = time.monotonic()
            elif time.monotonic() - empty_since >= settle_s:
                return

    def unplug(self) -> None:
        """Pull the cable: the pty closes and its name disappears, as a USB-serial adapter's
        /dev node does. (Left in place, the link would point at a /dev/pts/N that the kernel
        may give to another program's pty meanwhile, and the station would read its bytes.)"""
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        self.master = self.slave = -1
        if os.path.lexists(self.link):
            os.unlink(self.link)

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
        self.memory: list[tuple[str, int, str, int]] = []  # what a download sends back

    def tod_us(self) -> int:
        """Device time of day now: runs ``speed`` times faster than the wall clock."""
        return self.tod0_us + int((time.monotonic() - self.m0) * self.args.speed * 1e6)

    def wait_until(self, tod_us: int) -> None:
        while True:
            delay = (tod_us - self.tod_us()) / 1e6 / self.args.speed
            if delay <= 0:
                return
            time.sleep(min(delay, 0.05))

    def line(self, channel: str, tod_us: int, bib: str = "", edit: str = "") -> bytes:
        """An impulse line, or with ``edit`` ("clear" | "insert") the operator's edit of one.
        Without a bib an ALGE timer numbers every impulse (PC-Timer); TAG leaves it blank."""
        self.counter += 1
        p = self.args.protocol
        tod_us %= 86_400_000_000
        if p == "alge":
            flag = {"clear": "c", "insert": "i"}.get(edit, " ")
            number = bib or self.counter
            text = format_alge(channel, tod_us, number, flag=flag, checksum=self.args.checksum)
        elif p == "tag":
            kind = {"clear": "TC", "insert": "T+"}.get(edit, "TN")
            text = format_tag(channel, tod_us, self.counter, bib, self.day, kind)
        else:
            text = format_racetime(channel, tod_us, self.counter, int(bib or 0))
        if not edit or edit == "insert":
            self.memory.append((channel, tod_us, bib, self.counter))
        return text.encode("ascii") + LINE_END[p]

    def download(self) -> bytes:
        """A TAG memory download (``#DL``): DS, every impulse as AN with its bib, DE; an ALGE
        timer's memory as its dump sends it (``RSM``): every impulse again, flagged ``m``."""
        if self.args.protocol == "alge":
            return b"".join(
                format_alge(ch, tod_us, bib or n, flag="m", checksum=self.args.checksum).encode()
                + LINE_END["alge"]
                for ch, tod_us, bib, n in self.memory
            )

        def frame(data: str) -> bytes:
            return f"{data}\t{tag_cs16(data)}".encode("ascii") + LINE_END["tag"]

        out = frame("DS 01  00 START - FINISH     ")
        for seq, (channel, tod_us, bib, _n) in enumerate(self.memory, start=1):
            data = format_tag(channel, tod_us, seq, bib, self.day, "AN").split("\t")[0]
            out += frame(data)
        return out + frame("DE 01")

    def send(self, data: bytes) -> None:
        self.port.write(data)


def _channels(args: argparse.Namespace, n: int) -> list[str] | None:
    """The channel names of the n photocells, or None (after saying why) if they do not fit."""
    channels = args.channels.split(",") if args.channels else default_channels(args.protocol, n)
    if len(channels) != n:
        print(
            f"station-sim: error: {len(channels)} channels for {n} photocells",
            file=sys.stderr,
        )
        return None
    return channels


class Day:
    """The timer's day on the port: each planned line sent when due, with the quirks of the
    line (running time, garbage) and of the cable (unplugged after or during a descent)."""

    def __init__(
        self, args: argparse.Namespace, port: PtyPort, timer: Timer, sim: StraightRun,
        ids: list[str], channels: list[str],
    ) -> None:  # fmt: skip
        self.args = args
        self.port = port
        self.timer = timer
        self.stop = False
        signal.signal(signal.SIGTERM, self.on_signal)
        signal.signal(signal.SIGINT, self.on_signal)
        self.planner = Planner(args, sim, ids, channels, timer.rng, timer.tod_us())
        self.last_running = timer.tod_us() // 1_000_000 * 1_000_000
        self.unplugged_after: set[int] = set()
        # --unplug-during K:P: the cable comes out after descent K's P-th impulse and goes
        # back in --disconnect-s later, while the timer goes on timing into its memory
        self.during = (
            tuple(int(v) for v in args.unplug_during.split(":")) if args.unplug_during else None
        )
        self.sent: dict[int, int] = {}  # impulses sent per descent
        self.replug_at: float | None = None

    def on_signal(self, *_: object) -> None:
        self.stop = True

    def send_all(self, truth: TextIO | None) -> None:
        """Send every planned line when its time comes; write each descent's truth to
        ``truth`` (a file or None) once its last line is sent."""
        planner = self.planner
        while not self.stop:
            planner.plan_due()
            if not planner.heap:
                break
            ev = heapq.heappop(planner.heap)
            self._running_time(ev.tod)
            self._replug_before(ev.tod)
            self.timer.wait_until(ev.tod)
            self._garbage()
            self._send(ev)
            done = planner.line_sent(ev.k)
            if done is not None:
                if truth is not None:
                    truth.write(json.dumps(done) + "\n")
                    truth.flush()
                self._disconnect_after(ev.k)

    def _running_time(self, tod: int) -> None:
        """Running-time lines at every full second of the device clock (ALGE EMU1)."""
        if not (self.args.running_time and self.args.protocol == "alge"):
            return
        while self.last_running + 1_000_000 < tod and not self.stop:
            self.last_running += 1_000_000
            self.timer.wait_until(self.last_running)
            self.timer.send(format_tod(self.last_running, 1).encode() + b"\r")

    def _replug_before(self, tod: int) -> None:
        """Back in when due, not only at the next impulse."""
        if self.replug_at is None:
            return
        due_in = (tod - self.timer.tod_us()) / 1e6 / self.args.speed
        if self.replug_at <= time.monotonic() + due_in:
            time.sleep(max(self.replug_at - time.monotonic(), 0.0))
            self.port.plug()
            self.replug_at = None
            print("station-sim: plugged in again", file=sys.stderr, flush=True)

    def _garbage(self) -> None:
        """Garbage bytes on the line before a line, by chance (a noisy cable)."""
        rng = self.timer.rng
        if self.args.garbage and rng.random() < self.args.garbage:
            junk = bytes(rng.integers(0, 256, int(rng.integers(3, 20)), dtype=np.uint8))
            self.timer.send(junk.replace(b"\r", b"").replace(b"\n", b"") + b"\r")

    def _send(self, ev: Planned) -> None:
        """Send one planned line: an operator's edit or an impulse, which may pull the cable."""
        timer = self.timer
        if ev.kind.startswith("clear@"):
            timer.send(timer.line(ev.channel, int(ev.kind[6:]), ev.bib, "clear"))
            return
        if ev.kind.startswith("insert@"):
            timer.send(timer.line(ev.channel, int(ev.kind[7:]), ev.bib, "insert"))
            return
        timer.send(timer.line(ev.channel, ev.tod, ev.bib))
        self.sent[ev.k] = self.sent.get(ev.k, 0) + 1
        if self.during is not None and (ev.k + 1, self.sent[ev.k]) == self.during:
            self.port.drain()  # what was written is read before the cable comes out
            self.port.unplug()
            self.replug_at = time.monotonic() + self.args.disconnect_s
            print(f"station-sim: unplugged during descent {ev.k + 1}", file=sys.stderr, flush=True)

    def _disconnect_after(self, k: int) -> None:
        """Pull the cable after descent k if told to, and plug it in again --disconnect-s on."""
        args = self.args
        due = (args.disconnect_after and k + 1 == args.disconnect_after) or (
            args.disconnect_every and (k + 1) % args.disconnect_every == 0
        )
        if not due or k in self.unplugged_after:
            return
        self.unplugged_after.add(k)
        self.port.drain()  # what was written is read before the cable comes out
        self.port.unplug()
        print(f"station-sim: unplugged after descent {k + 1}", file=sys.stderr, flush=True)
        time.sleep(args.disconnect_s)
        self.port.plug()
        print("station-sim: plugged in again", file=sys.stderr, flush=True)

    def end(self) -> None:
        """The end of the day: the cable back in, the memory downloaded, the port held."""
        args, port, timer = self.args, self.port, self.timer
        if self.replug_at is not None:
            port.plug()  # back in for the end of the day
        if args.download_to and args.protocol in ("tag", "alge"):
            # the timer's memory saved by its own download program, for `station import`
            with open(args.download_to, "wb") as fh:
                fh.write(timer.download())
        if args.download and args.protocol == "tag" and not self.stop:
            timer.send(timer.download())
        # leave the port open a moment so the last bytes are read, unless told to hold it
        port.drain(timeout_s=max(args.hold, 0.5))
        end_t = time.monotonic() + args.hold
        while time.monotonic() < end_t and not self.stop:
            time.sleep(0.05)


def run(args: argparse.Namespace) -> int:
    track = build_track(load_survey(args.survey))
    ids = track.photocell_ids
    channels = _channels(args, len(ids))
    if channels is None:
        return 2
    if args.protocol == "microgate" and (args.clear or args.insert):
        print("station-sim: a Racetime2 sends no edits; --clear/--insert ignored", file=sys.stderr)
    xs = np.array([pc.x for pc in track.photocells])
    sim = StraightRun(track.profile, xs)
    port = PtyPort(args.link)
    print(f"PORT {port.link}", flush=True)
    if args.wait_reader > 0 and not port.wait_for_reader(args.wait_reader):
        print("station-sim: nobody opened the port; starting anyway", file=sys.stderr, flush=True)
    timer = Timer(args, port)
    truth = open(args.truth, "a", encoding="utf-8") if args.truth else None  # noqa: SIM115
    day = Day(args, port, timer, sim, ids, channels)
    try:
        day.send_all(truth)
        day.end()
    finally:
        if truth is not None:
            truth.close()
        port.close()
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="station-sim", description=__doc__.splitlines()[0].replace("``", "")
    )  # no reST markup on screen
    _timer_options(ap)
    _descent_options(ap)
    _quirk_options(ap)
    _port_options(ap)
    return ap


def _timer_options(ap: argparse.ArgumentParser) -> None:
    """The timer, its protocol and its clock."""
    ap.add_argument("--version", action="version", version=f"station-sim {__version__}")
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


def _descent_options(ap: argparse.ArgumentParser) -> None:
    """The skiers' physics, their skis and the timing noise."""
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


def _quirk_options(ap: argparse.ArgumentParser) -> None:
    """The field quirks: photocells, the line, bibs, overlapping skiers, operator edits."""
    ap.add_argument("--double-trigger", type=float, default=0.0, metavar="P")
    ap.add_argument("--miss", type=float, default=0.0, metavar="P", help="miss a middle photocell")
    ap.add_argument(
        "--walkthrough", type=float, default=0.0, metavar="P", help="lone start impulses"
    )
    ap.add_argument("--running-time", action="store_true", help="ALGE running-time lines")
    ap.add_argument(
        "--garbage", type=float, default=0.0, metavar="P", help="garbage bytes per line"
    )
    ap.add_argument(
        "--bibs",
        action="store_true",
        help="the descent's number as bib on its impulses (default: ALGE numbers "
        "every impulse, PC-Timer counter mode; TAG and Microgate send none)",
    )
    ap.add_argument(
        "--overlap",
        type=float,
        default=0.0,
        metavar="S",
        help="start a skier every S seconds, before the one ahead has finished",
    )
    ap.add_argument(
        "--clear",
        type=float,
        default=0.0,
        metavar="P",
        help="a false start the operator clears (ALGE c, TAG TC), per descent",
    )
    ap.add_argument(
        "--insert",
        type=float,
        default=0.0,
        metavar="P",
        help="a middle photocell missed and typed in (ALGE i, TAG T+), per descent",
    )


def _port_options(ap: argparse.ArgumentParser) -> None:
    """The memory download, the port and its cable, the truth file."""
    ap.add_argument(
        "--download",
        action="store_true",
        help="TAG: send a memory download (DS, AN …, DE) at the end",
    )
    ap.add_argument(
        "--download-to",
        metavar="FILE",
        help="TAG and ALGE: write the memory download (TAG: DS, AN …, DE; ALGE: every "
        "impulse again, flagged m) to FILE at the end",
    )
    ap.add_argument(
        "--wait-reader",
        type=float,
        default=30.0,
        metavar="S",
        help="wait up to S s for the station to open the port before the clock "
        "starts (0: do not wait)",
    )
    ap.add_argument("--disconnect-after", type=int, default=0, metavar="K")
    ap.add_argument(
        "--disconnect-every",
        type=int,
        default=0,
        metavar="K",
        help="unplug after every K-th descent (soak test of reconnects)",
    )
    ap.add_argument(
        "--unplug-during",
        metavar="K:P",
        help="unplug after the P-th impulse of descent K, for --disconnect-s, the timer "
        "timing on into its memory",
    )
    ap.add_argument("--disconnect-s", type=float, default=2.0)
    ap.add_argument(
        "--hold", type=float, default=2.0, help="seconds to keep the port after the end"
    )
    ap.add_argument("--link", help="path of the symlink to the pty (default: a temp dir)")
    ap.add_argument("--truth", help="append each descent's truth as JSON lines to this file")


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
