"""The one live comparison of the day's items, for the UI's panel and ``station record``'s
console alike, computed in a process of its own.

At 2000 descents the day's joint fit takes seconds of Python and numpy. On a thread of the
recording's process it would hold the interpreter's lock against the next descent's fit and
the UI's drawing of it. Here a process keeps the day's results (each sent once, when it is
fitted or marked) and computes the :class:`DayComparison` when asked; this side is a thread
that waits for it without the lock.

Computed only while a view shows it (and once more when the source ended, shown or not),
after the results have been quiet for ``QUIET_S`` (a replay: one comparison at the end, not one
per descent), from the latest results whatever arrived while it ran.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import BinaryIO

from station.session.analysis import DescentResult
from station.session.comparison import DayComparison, compare_results
from station.survey.track import Track

#: the comparison waits until the results have not changed for this long (s)
QUIET_S = 0.3
#: pickles between the recording and the process (both the same Python)
PROTOCOL = pickle.HIGHEST_PROTOCOL
#: how long closing waits for the process to end before it is killed (s): quitting
#: does not wait for a comparison under way
STOP_WAIT_S = 0.2


def serve(inp: BinaryIO, out: BinaryIO) -> None:
    """The comparison process: pickled requests in, pickled replies out. ``("track", t)``
    first, then ``("put", results)`` and ``("compare",)``, answered ``("ok", comparison)`` or
    ``("error", why)``; ``("stop",)`` or the end of its input ends it."""
    track: Track | None = None
    results: dict[int, DescentResult] = {}
    while True:
        try:
            msg = pickle.load(inp)
        except (EOFError, OSError):  # the recording has gone
            return
        kind = msg[0]
        if kind == "track":
            track = msg[1]
        elif kind == "put":
            for res in msg[1]:
                results[res.number] = res
        elif kind == "compare":
            try:
                assert track is not None, "no track"
                reply: tuple[str, object] = ("ok", live_comparison(track, results))
            except Exception as exc:  # noqa: BLE001 - the comparison is a view: said, not raised
                reply = ("error", f"{type(exc).__name__}: {exc}")
            pickle.dump(reply, out, PROTOCOL)
            out.flush()
        else:  # "stop"
            return


def live_comparison(track: Track, results: dict[int, DescentResult]) -> DayComparison:
    """The day's comparison as the live views show it: none before two fitted descents."""
    day = compare_results(track, [results[n] for n in sorted(results)], at_least=2)
    return day.summary()


def main() -> None:
    """``python -m station.session.comparing``: stdin and stdout are the pipe to the
    recording; whatever else would go to stdout (a library's print) goes to stderr."""
    # the fit and the UI's drawing of it come first where the two share the cores
    with contextlib.suppress(OSError):
        os.nice(10)
    channel = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    serve(sys.stdin.buffer, channel)


def portable(res: DescentResult) -> DescentResult:
    """A result as the comparison's process needs it: its fit in it (read back here, on the
    comparison's thread, where a recording keeps it in the session's fit store), no speed
    curve."""
    if res.stored is None and res.speed_x is None and res.speed_v is None:
        return res
    return replace(res, kept_fit=res.fit, stored=None, handle=None, speed_x=None, speed_v=None)


class Comparer:
    """The day's comparison: ``update`` with each result fitted or marked, ``show`` while a
    view shows it; ``post`` gets each new :class:`DayComparison`, ``warn`` a failure.

    ``update`` and ``show`` only note what changed (the fit worker's and the UI's handlers
    stay short); a thread of this object sends the results and waits for the comparison."""

    #: the comparison's process (a test starts a slow one)
    command: tuple[str, ...] = (sys.executable, "-m", "station.session.comparing")

    def __init__(
        self,
        track: Track,
        post: Callable[[DayComparison], object],
        warn: Callable[[str], object],
        *,
        quiet_s: float = QUIET_S,
    ) -> None:
        self.track = track
        self.post = post
        self.warn = warn
        self.quiet_s = quiet_s
        self._cond = threading.Condition()
        self._pending: dict[int, DescentResult] = {}  # not sent to the process yet
        self._sent: dict[int, DescentResult] = {}  # sent: again to a new process
        self._dirty = False
        self._changed_at = 0.0
        self._shown = False
        self._ended = False  # the source ended: computed, shown or not
        self._closed = False
        self.busy = False  # a comparison is being computed (the benchmark looks)
        self._proc: subprocess.Popen[bytes] | None = None
        self._thread = threading.Thread(target=self._loop, name="comparison", daemon=True)
        self._thread.start()

    def update(self, res: DescentResult) -> None:
        """A descent fitted, refitted or marked: the comparison is due (when shown)."""
        with self._cond:
            self._pending[res.number] = res
            self._dirty = True
            self._changed_at = time.monotonic()
            self._cond.notify_all()

    def show(self, shown: bool) -> None:
        """The comparison opened (True) or closed (False): computed only while shown."""
        with self._cond:
            self._shown = shown
            self._cond.notify_all()

    def source_ended(self) -> None:
        """The source ended: the whole day's comparison, shown or not (and from now on)."""
        with self._cond:
            self._ended = True
            self._dirty = True
            self._cond.notify_all()

    def close(self, wait_s: float = 0.0) -> None:
        """The process ends. ``wait_s``: how long the comparison due (the source's end) may
        take to be posted first; 0: one under way is not waited for (quitting the UI)."""
        deadline = time.monotonic() + wait_s
        with self._cond:
            while (self._dirty and (self._shown or self._ended)) or self.busy:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cond.wait(left)
            self._closed = True
            self._cond.notify_all()
        self._drop_process(ask=True)

    @property
    def closed(self) -> bool:
        return self._closed

    # -- the thread

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not (self._closed or (self._dirty and (self._shown or self._ended))):
                    self._cond.wait()
                if self._closed:
                    return
                quiet = self._changed_at + self.quiet_s - time.monotonic()
                if quiet > 0:  # debounced: results still arriving
                    self._cond.wait(quiet)
                    continue
                batch, self._pending = self._pending, {}
                self._dirty = False
                self.busy = True
            try:
                reply = self._ask(list(batch.values()))
            except Exception as exc:  # noqa: BLE001 - the process died: a new one next time
                if self.closed:  # closing ended it
                    return
                self._drop_process()
                reply = ("error", f"{type(exc).__name__}: {exc}")
            try:
                kind, answer = reply
                if kind == "ok" and isinstance(answer, DayComparison):
                    self.post(answer)
                else:
                    self.warn(f"comparison failed: {answer}")
            finally:
                with self._cond:  # posted: closing may go on
                    self.busy = False
                    self._cond.notify_all()

    def _ask(self, batch: list[DescentResult]) -> tuple[str, object]:
        """Send what changed, get the comparison: the thread waits on the pipe, not on the
        lock."""
        batch = [portable(res) for res in batch]
        for res in batch:
            self._sent[res.number] = res
        proc = self._proc
        if proc is None:  # a new process: the track and the whole day
            proc = self._start()
            batch = list(self._sent.values())
        assert proc.stdin is not None and proc.stdout is not None
        if batch:
            pickle.dump(("put", batch), proc.stdin, PROTOCOL)
        pickle.dump(("compare",), proc.stdin, PROTOCOL)
        proc.stdin.flush()
        reply: tuple[str, object] = pickle.load(proc.stdout)
        return reply

    def _start(self) -> subprocess.Popen[bytes]:
        # a process of its own started afresh (not a fork of the recording's, whose threads
        # hold locks), as the simulated timer is: multiprocessing's start needs a real
        # stderr, and the UI replaces it
        proc = subprocess.Popen(
            list(self.command),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        assert proc.stdin is not None
        pickle.dump(("track", self.track), proc.stdin, PROTOCOL)
        self._proc = proc
        return proc

    def _drop_process(self, ask: bool = False) -> None:
        """End the process: asked (closing), or killed (it failed)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if ask and proc.stdin is not None:  # the end of its input ends it
            with contextlib.suppress(OSError, ValueError):
                proc.stdin.close()
        try:
            proc.wait(STOP_WAIT_S if ask else 0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        for f in (proc.stdin, proc.stdout):
            if f is not None:
                with contextlib.suppress(OSError):
                    f.close()


if __name__ == "__main__":
    main()
