"""The process's garbage-collector and BLAS policy, in one place: each command and the UI say
which phase they are in (a bounded command, a bulk replay, an app's long-lived set-up), and
this module decides what Python's collector and the BLAS thread pool do in it.

BLAS runs on one thread: the station's matrices are small (a spline's 70 × 70, a fit's 9 × 4,
a day's joint fit), a pool gains nothing on them, and on a busy machine (the terminal UI and
its fit worker, a shared laptop) each threaded LAPACK call waits for a busy core while the idle
pool spins beside the imports. Measured on a loaded 2-core machine: the spline's one 68 × 68
eigh in ``station fit`` took 70-90 ms in two runs of three, 0.5 ms with one thread; importing
numpy and scipy took 0.83 s of CPU with the pool, 0.72 s without; a pool made a 50-descent
joint fit 20x slower.

The collector is kept out of work that makes objects by the hundred thousand and no garbage
cycles (imports, replays), and the UI's full collections run between descents
(:class:`IdleCollector`), not whenever an allocation tips Python's count.
"""

from __future__ import annotations

import contextlib
import gc
import os
import sys
import time
from collections.abc import Iterator

BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")
#: OpenBLAS was loaded with one thread (set by :func:`one_blas_thread` before numpy)
_one_from_the_start = False


def one_blas_thread() -> None:
    """Cap OpenBLAS at one thread for this process, unless the user chose a number. OpenBLAS
    reads the variable once, when numpy loads, so this runs before any command imports numpy;
    in a process that already has numpy (tests calling ``main``) it does nothing."""
    global _one_from_the_start
    if "numpy" in sys.modules:
        return
    if not any(v in os.environ for v in BLAS_THREAD_VARS):
        os.environ["OPENBLAS_NUM_THREADS"] = "1"
    _one_from_the_start = os.environ.get("OPENBLAS_NUM_THREADS") == "1"


@contextlib.contextmanager
def blas_on_one_thread() -> Iterator[None]:
    """BLAS on one thread while the block runs, whatever the process loaded it with (a library
    caller, a test, the UI's process). When OpenBLAS was loaded with one thread there is
    nothing to change, and threadpoolctl (its import and its look at every loaded library,
    ~50 ms on a loaded machine) is left out."""
    if _one_from_the_start:
        yield
        return
    from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

    with threadpool_limits(limits=1, user_api="blas"):
        yield


@contextlib.contextmanager
def collector_off() -> Iterator[None]:
    """No collection while a bounded command runs (a fit: mostly importing numpy and scipy,
    hundreds of thousands of objects and no garbage worth collecting; the collections cost some
    8 % of that import's CPU). The collector is given back, also when the block raises."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


@contextlib.contextmanager
def set_up_frozen() -> Iterator[None]:
    """What exists now (modules, the track, the grids) out of the collector's scans while the
    block makes and keeps objects by the hundred thousand (a replay)."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@contextlib.contextmanager
def bulk_without_collector() -> Iterator[None]:
    """A bulk pass that makes no garbage cycles (tuples, lists and descents, kept or freed by
    their counts): the collector is off while it runs (it scanned the growing lists again and
    again: 15 % of a replay's time), and the set-up is frozen out of its later scans. What the
    block made joins the frozen set before the collector is back: else its first collection
    walked every object made while it was off (25 ms of a 100 800-line capture's 330)."""
    gc.freeze()
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if was_enabled:
            gc.enable()
        gc.unfreeze()


def freeze_long_lived() -> None:
    """What lives as long as the app (the libraries, the screen) out of the collector's way,
    or every full collection of the day walks it again; :func:`thaw` gives it back."""
    gc.collect()
    gc.freeze()


def thaw() -> None:
    """Everything frozen back in the collector's reach (the app ends; a test goes on)."""
    gc.unfreeze()


#: the oldest generation's threshold while the UI decides (a C int): never reached
NEVER = 2**31 - 1
#: after a full collection, the next one no sooner than this many times its length
SPACING = 10.0


class IdleCollector:
    """The UI's full collections, at moments the UI chooses: between descents.

    A full collection walks every object the UI's process keeps (the day's descents and fits,
    the table's rows, the caches of what was drawn): near descent 800 one took 100–300 ms, and
    Python started one every seven descents or so, often between a descent's last impulse and
    its fit on the screen (benchmarks/ui_fit_latency.py). Here Python is told never to start
    one itself; the UI asks :meth:`collect_if_due` when a descent's fit has been drawn and at a
    slow pace in between. One is due as often as Python would consider one (``threshold2``
    collections of the middle generation since the last), and no sooner than ``SPACING`` times
    its own length after the last. Nothing is left out: every cycle that becomes garbage is
    collected, seconds later at most. The young generations are collected by Python as before.
    """

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
