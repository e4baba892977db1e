"""The UI's comparison of the day's items, computed in a process of its own.

At 2000 descents the day's joint fit takes seconds of Python and numpy. On a thread of the
UI's process it held the interpreter's lock against the next descent's fit and the UI's
drawing of it: a descent that ended while the comparison ran reached the screen hundreds of
milliseconds late (issue 19: ≤ 50 ms is the target). Here a process keeps the day's results
(each sent once, when it is fitted or marked) and computes the comparison's text when asked;
the UI's side is a thread that waits for it without the lock.

Computed only while the comparison is shown (and once more when a replay ended, shown or not),
after the results have been quiet for ``QUIET_S`` (a replay: one comparison at the end, not one
per descent), from the latest results whatever arrived while it ran. No Textual here: the
process imports what the comparison needs, nothing of the UI.
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
from station.survey.track import Track

#: the comparison waits until the results have not changed for this long (s)
QUIET_S = 0.3
#: pickles between the UI and the process (both the same Python)
PROTOCOL = pickle.HIGHEST_PROTOCOL
#: how long closing waits for the process to end before it is killed (s): quitting the UI
#: does not wait for a comparison under way
STOP_WAIT_S = 0.2


def serve(inp: BinaryIO, out: BinaryIO) -> None:
    """The comparison process: pickled requests in, pickled replies out. ``("track", t)``
    first, then ``("put", results)`` and ``("text",)``, answered ``("ok", text)`` or
    ``("error", why)``; ``("stop",)`` or the end of its input ends it."""
    from station.session.acquisition import comparison_text

    track: Track | None = None
    results: dict[int, DescentResult] = {}
    while True:
        try:
            msg = pickle.load(inp)
        except (EOFError, OSError):  # the UI has gone
            return
        kind = msg[0]
        if kind == "track":
            track = msg[1]
        elif kind == "put":
            for res in msg[1]:
                results[res.number] = res
        elif kind == "text":
            try:
                assert track is not None, "no track"
                reply = ("ok", comparison_text(track, [results[n] for n in sorted(results)]))
            except Exception as exc:  # noqa: BLE001 - the comparison is a view: said, not raised
                reply = ("error", f"{type(exc).__name__}: {exc}")
            pickle.dump(reply, out, PROTOCOL)
            out.flush()
        else:  # "stop"
            return


def main() -> None:
    """``python -m station.ui.comparison``: stdin and stdout are the pipe to the UI; whatever
    else would go to stdout (a library's print) goes to stderr."""
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


class ComparisonProcess:
    """The day's comparison for the UI: ``update`` with each result the UI is given, ``show``
    while the comparison is on the screen; ``post`` gets each new text, ``warn`` a failure.

    ``update`` and ``show`` only note what changed (the UI's handlers stay short); a thread of
    this object sends the results and waits for the text."""

    def __init__(
        self,
        track: Track,
        post: Callable[[str], object],
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
        """A replay ended: the whole day's comparison, shown or not (and from now on)."""
        with self._cond:
            self._ended = True
            self._dirty = True
            self._cond.notify_all()

    def close(self) -> None:
        """The process ends (a comparison under way is not waited for)."""
        with self._cond:
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
                self.warn(f"comparison failed: {type(exc).__name__}: {exc}")
                continue
            finally:
                self.busy = False
            kind, text = reply
            if kind == "ok":
                self.post(text)
            else:
                self.warn(f"comparison failed: {text}")

    def _ask(self, batch: list[DescentResult]) -> tuple[str, str]:
        """Send what changed, get the text: the thread waits on the pipe, not on the lock."""
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
        pickle.dump(("text",), proc.stdin, PROTOCOL)
        proc.stdin.flush()
        reply: tuple[str, str] = pickle.load(proc.stdout)
        return reply

    def _start(self) -> subprocess.Popen[bytes]:
        # a process of its own started afresh (not a fork of the UI's, whose threads hold
        # locks), as the simulated timer is: multiprocessing's start needs a real stderr,
        # and Textual replaces it
        proc = subprocess.Popen(
            [sys.executable, "-m", "station.ui.comparison"],
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
