"""The two ways a whole day goes through the acquisition loop: ``station record`` from the
timer until it is stopped, and a replay of a session or a capture in line."""

from __future__ import annotations

import datetime as dt
import signal
import threading
import time
from collections.abc import Callable

from station.session.acquisition import FINAL_COMPARISON_S, Acquisition
from station.session.analysis import FitCache
from station.session.config import StationConfig
from station.session.listener import Listener, QuietListener
from station.session.replay import source_date


def record(
    config: StationConfig,
    session_dir: str,
    listener: Listener,
    max_descents: int | None = None,
    duration_s: float | None = None,
    started: Callable[[], None] | None = None,
) -> Acquisition:
    """Record headless until SIGINT/SIGTERM, ``max_descents`` or ``duration_s``; any of them
    ends the open descent the same way (:meth:`Acquisition.close`). ``started`` is called once
    the session folder is made and the raw log open (not for a folder refused)."""
    from station.session.serialport import ensure_port_free

    ensure_port_free(config.serial)  # a second recorder on the port: one line, no session made
    # compare, shown all along: the console says after every descent whether the day is
    # decided
    acq = Acquisition.open(config, listener, session_dir=session_dir, compare=True)
    acq.show_comparison(True)
    if started is not None:
        started()
    stop = threading.Event()
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda *_: stop.set())
    t_end = None if duration_s is None else time.monotonic() + duration_s
    try:
        acq.start_serial()
        while not stop.is_set() and acq.reading:
            if t_end is not None and time.monotonic() >= t_end:
                break
            if max_descents is not None and acq.finished_descents >= max_descents:
                break
            stop.wait(0.1)
    finally:
        acq.close(comparison_wait_s=FINAL_COMPARISON_S)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if acq.source_error is not None:
        raise acq.source_error
    return acq


def replay(
    source: str,
    config: StationConfig,
    listener: Listener | None = None,
    speed: float | None = None,
    date: dt.date | None = None,
    warnings: list[str] | None = None,
    fits: FitCache | None = None,
    speed_curves: bool = True,
) -> Acquisition:
    """Feed a session (with its annotations) or a plain capture through the loop, in line.
    Without a listener the replay says nothing as it goes: the caller reports its results
    (and ``warnings`` collects what the raw log's reader passed over). ``fits``: the fits
    stored with the session, used where they fit and added to; ``speed_curves``: the fitted
    speed along the run of each descent (for the views that draw it)."""
    from station import runtime

    acq = Acquisition.open(
        config, listener or QuietListener(), date=source_date(source, date), threaded=False
    )
    acq.day.analyser.fits = fits
    acq.day.analyser.speed_curves = speed_curves
    # a replay makes objects by the hundred thousand and keeps most: the garbage collector
    # need not scan the set-up's (modules, the track, the grids) at every full collection
    with runtime.set_up_frozen():
        acq.replay(source, speed, warnings)
        acq.close()
    return acq
