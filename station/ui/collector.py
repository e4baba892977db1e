"""The UI's full garbage collections, at moments the UI chooses: between descents.

A full collection walks every object the process keeps, and the UI's process keeps the day
(the acquisition's descents and fits, the table's rows, the caches of what was drawn): near
descent 800 one took 100–300 ms, and Python started one every seven descents or so, from
whichever thread allocated at that moment: often between a descent's last impulse and its
fit on the screen (benchmarks/ui_fit_latency.py; issue 19's target for that is 50 ms).

Here Python is told never to start one itself, and the UI asks
:meth:`IdleCollector.collect_if_due` when a descent's fit has been drawn, and at a slow pace
in between, and then only when no descent is about to end. One is due as often as Python
would consider one (``threshold2`` collections of the middle generation since the last), and
no sooner than ``SPACING`` times its own length after the last (a collection of 0.2 s at
most every 2 s: a tenth of the UI's time at most, on a day of descents fed as fast as they
can be; at the trackside, descents a minute apart, after nearly every descent). Nothing is
frozen or left out: every cycle that becomes garbage is collected, seconds later at most.
(Python's other condition, the objects that reached the oldest generation since the last
full collection a quarter of those it kept, cannot be read from Python without a walk of
that generation: 20–60 ms at descent 800.) The young generations are collected by Python as
before (a few ms each).
"""

from __future__ import annotations

import gc
import time

#: the oldest generation's threshold while the UI decides (a C int): never reached
NEVER = 2**31 - 1
#: after a full collection, the next one no sooner than this many times its length
SPACING = 10.0


class IdleCollector:
    """Full collections only when asked, and only when one is due."""

    def __init__(self) -> None:
        self.saved = gc.get_threshold()
        self.next_at = 0.0  # time.monotonic() from which the next one may run
        self.collections = 0
        self.seconds = 0.0  # spent in them
        self.started = False

    def start(self) -> None:
        """From now on Python starts no full collection itself."""
        if not self.started:
            self.saved = gc.get_threshold()
            gc.set_threshold(self.saved[0], self.saved[1], NEVER)
            self.started = True

    def stop(self) -> None:
        """Python's thresholds back (the app ends; a test goes on in the same process)."""
        if self.started:
            gc.set_threshold(*self.saved)
            self.started = False

    def due(self) -> bool:
        """As many middle collections since the last full one as Python waits for, and the
        spacing after the last one kept."""
        return gc.get_count()[2] > self.saved[2] and time.monotonic() >= self.next_at

    def collect_if_due(self) -> bool:
        """A full collection if one is due (True: it ran)."""
        if not self.due():
            return False
        start = time.monotonic()
        gc.collect(2)
        took = time.monotonic() - start
        self.next_at = start + took * (1 + SPACING)
        self.collections += 1
        self.seconds += took
        return True
