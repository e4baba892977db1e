"""The simulated timer's descents, planned ahead of its clock.

Each descent's skier comes from the options (fixed, drawn per descent, or a test design of ski
pairs), its crossing times from the physics of :mod:`station.model.physics` plus timing noise,
and its field quirks (missed or doubled impulses, walk-throughs, operator edits) from the seeded
generator, drawn in one fixed order so that a run is reproducible.
"""

from __future__ import annotations

import argparse
import heapq
import sys
from dataclasses import dataclass, field

import numpy as np

from station.model.physics import Conditions, Params, StraightRun


@dataclass(order=True)
class Planned:
    """One line the timer will send: at ``tod`` (device time), for descent ``k``."""

    tod: int
    seq: int
    channel: str = field(compare=False)
    # impulse | double | walkthrough | false-start | clear@TOD | insert@TOD (the time edited)
    kind: str = field(compare=False)
    k: int = field(compare=False)
    bib: str = field(compare=False, default="")


class Planner:
    """The descents, each planned when the clock reaches it: its lines go on a heap in device
    time, its truth is kept until its last line is sent. The draws from the seeded generator
    come in one fixed order, which is what makes a run reproducible."""

    def __init__(
        self, args: argparse.Namespace, sim: StraightRun, ids: list[str], channels: list[str],
        rng: np.random.Generator, now_tod_us: int,
    ) -> None:  # fmt: skip
        self.args = args
        self.sim = sim
        self.ids = ids
        self.channels = channels
        self.rng = rng
        self.skis = [float(v) for v in args.skis.split(",")] if args.skis else []
        self.interval = args.overlap if args.overlap else args.interval
        first_start = now_tod_us + int(args.first_after * args.speed * 1e6)
        self.first_start = -(-first_start // 1_000_000) * 1_000_000  # whole seconds
        self.edits = args.protocol != "microgate"
        self.next_start = self.first_start
        self.prev_end: int | None = None  # None before the first descent
        self.k = 0
        self.seq = 0
        self.heap: list[Planned] = []
        self.truths: dict[int, dict] = {}
        self.remaining: dict[int, int] = {}  # lines of each descent still to send

    def params(self, k: int, start: int) -> Params:
        """Descent k's skier: fixed, drawn per descent, or a pair of skis of a test design."""
        args, rng, skis = self.args, self.rng, self.skis
        drift = args.mu_drift_per_hour * (start - self.first_start) / 3.6e9
        if skis and args.order:
            # a test design: pairs in the given order, one tuck (CdA) for the skier, the
            # track drifting; only v0 varies from descent to descent
            pair = ord(args.order[k % len(args.order)].upper()) - ord("A")
            return Params(cda=args.cda, mu=skis[pair] + drift, v0=float(rng.uniform(2.5, 4.5)))
        if skis:
            # pairs of skis in rotation, each with its own friction; the skier varies a little
            return Params(
                cda=float(rng.normal(0.22, 0.01)),
                mu=skis[k % len(skis)] * float(rng.normal(1.0, 0.03)) + drift,
                v0=float(rng.uniform(2.5, 4.5)),
            )
        if args.vary:
            return Params(
                cda=float(rng.uniform(0.18, 0.30)),
                mu=float(rng.uniform(0.006, 0.030)),
                v0=float(rng.uniform(2.0, 6.0)),
            )
        return Params(args.cda, args.mu, args.v0, args.mu1)

    def push(self, tod: int, channel: str, kind: str, k: int, bib: str) -> None:
        self.seq += 1
        heapq.heappush(self.heap, Planned(tod, self.seq, channel, kind, k, bib))
        self.remaining[k] = self.remaining.get(k, 0) + 1

    def plan_due(self) -> None:
        """Plan descents until the next one starts after the earliest line still to send."""
        while self.k < self.args.descents and (
            not self.heap or self.next_start <= self.heap[0].tod
        ):
            self.plan_next()

    def plan_next(self) -> None:
        """Plan the next descent: its lines go on the heap, its truth is kept until sent."""
        args = self.args
        k = self.k
        self.k += 1
        start = -(-self.next_start // 1_000_000) * 1_000_000  # on a whole second
        p = self.params(k, start)
        d = self.sim.solve(p, Conditions(args.mass, args.air_density), sensitivities=False)
        if d.stopped_x is not None:
            print(f"station-sim: descent {k + 1} would stop; skipped", file=sys.stderr)
            self.next_start = start + int(self.interval * 1e6)
            return
        noise = self.rng.normal(0.0, args.noise_ms * 1e-3, len(d.t) - 1)
        t = d.t + np.concatenate([[0.0], noise])
        bib = str((k % 9999) + 1) if args.bibs else ""
        inserted = self._pick_inserted()
        sent_ids, end = self._plan_impulses(k, start, t, bib, inserted)
        if inserted is not None:
            tod = start + int(round(t[inserted] * 1e6))
            self.push(end + 1_000_000, self.channels[inserted], f"insert@{tod}", k, bib)
        self._plan_walkthrough(k, start)
        cleared = self._plan_false_start(k, start, bib)
        self.truths[k] = {
            "descent": k + 1,
            "bib": bib,
            "cda": p.cda,
            "mu": p.mu,
            "v0": p.v0,
            "mu1": p.mu1,
            "pair": args.order[k % len(args.order)] if args.order else None,
            "start_tod_us": start,
            "photocells": sent_ids,
            "t": [float(x) for x in t],
            "inserted": self.ids[inserted] if inserted is not None else None,
            "false_start_cleared": cleared,
        }
        self.prev_end = end
        nxt = start + int(self.interval * 1e6)
        if not args.overlap:
            nxt = max(nxt, end + 1_000_000)  # one skier at a time
        self.next_start = nxt

    def _pick_inserted(self) -> int | None:
        """The middle photocell the timer misses and the operator types in, if any."""
        args, n = self.args, len(self.ids)
        if self.edits and args.insert and self.rng.random() < args.insert and n > 2:
            return int(self.rng.integers(1, n - 1))
        return None

    def _plan_impulses(
        self, k: int, start: int, t: np.ndarray, bib: str, inserted: int | None
    ) -> tuple[list[str], int]:
        """Push the descent's impulses (missed, doubled by chance); return the photocells
        that report it and the device time of its last crossing."""
        args, rng, ids = self.args, self.rng, self.ids
        sent_ids = []
        end = start
        for i, (ch, ti) in enumerate(zip(self.channels, t, strict=True)):
            tod = start + int(round(ti * 1e6))
            end = max(end, tod)
            if i == inserted:
                sent_ids.append(ids[i])
                continue  # the timer missed it; the operator types it in later
            if 0 < i < len(ids) - 1 and rng.random() < args.miss:
                continue
            self.push(tod, ch, "impulse", k, bib)
            sent_ids.append(ids[i])
            if rng.random() < args.double_trigger:
                self.push(tod + int(rng.uniform(0.02, 0.15) * 1e6), ch, "double", k, bib)
        return sent_ids, end

    def _plan_walkthrough(self, k: int, start: int) -> None:
        """Someone walks through the start beam between two descents, by chance."""
        prev_end = self.prev_end
        if (
            self.args.walkthrough
            and self.rng.random() < self.args.walkthrough
            and (prev_end is not None)
        ):
            self.push((prev_end + start) // 2, self.channels[0], "walkthrough", k, "")

    def _plan_false_start(self, k: int, start: int, bib: str) -> bool:
        """A false start, cleared by the operator before the real one, by chance."""
        args = self.args
        if not (self.edits and args.clear and self.rng.random() < args.clear):
            return False
        fs = start - int(self.rng.uniform(2.0, 4.0) * 1e6)
        self.push(fs, self.channels[0], "false-start", k, bib)
        self.push(fs + 500_000, self.channels[0], f"clear@{fs}", k, bib)
        return True

    def line_sent(self, k: int) -> dict | None:
        """Count one of descent k's lines as sent; its truth once it was the last."""
        self.remaining[k] -= 1
        return self.truths.pop(k) if self.remaining[k] == 0 else None
