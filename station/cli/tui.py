"""Running the trackside terminal UI from a command: ``live`` and ``demo`` (terminal.py) and
``replay --ui`` (recording.py) share it. Not a command module.

The UI (:mod:`station.ui.app`) is imported inside the functions that start it: Textual and the
UI's modules take 0.26 s to import on the 2-core test machine (measured after the session
modules are loaded), which ``replay`` without ``--ui``, ``record`` and ``export`` would pay for
nothing.
"""

from __future__ import annotations

import os
import sys
from typing import Any

from station.cli.console import annotate_session
from station.errors import InputError
from station.report.text import count
from station.session.config import StationConfig
from station.session.replay import source_date


def require_terminal(command: str, instead: str) -> None:
    """The UI needs a terminal to read keys from and to draw on (Textual draws on stderr): with
    input or output redirected it would write escape codes into a file and run until killed."""
    streams = {"standard input": sys.stdin, "standard output": sys.stdout}
    streams["standard error"] = sys.stderr
    for name, stream in streams.items():
        try:
            tty = stream is not None and stream.isatty()
        except (AttributeError, ValueError):  # closed or replaced by something without a fd
            tty = False
        if not tty:
            raise InputError(
                f"station {command} is a terminal UI and {name} is not a terminal; "
                f"run it in a terminal ({instead})"
            )


def replay_ui(cfg: StationConfig, source: str, speed: float | None, date: Any) -> int:
    """``station replay --ui``: a session through its :class:`RecordedSession`, a plain
    capture as it is; what was entered in a session's replay is saved in it at the end."""
    from station.ui.app import StationApp  # here: Textual, see the module's note

    require_terminal("replay --ui", "without --ui, replay prints the results")
    date = source_date(source, date)
    app = StationApp(cfg, mode="replay", source=source, speed=speed, date=date)
    return run_ui(app, then=lambda: save_kept(app))


def save_kept(app: Any) -> int:
    """What the engineer entered while replaying a session, saved in it as ``station annotate``
    saves it (results.csv rewritten unless a recorder owns it): a replay records nothing, and
    a mark that vanished at quit would be a result silently different from the one seen."""
    if not app.kept:
        return 0
    try:
        said = annotate_session(app.recorded, app.kept)
    except InputError as exc:
        print(f"station replay: error: what was entered is not saved: {exc}", file=sys.stderr)
        return 2
    print(said, file=sys.stderr, flush=True)
    return 0


def run_ui(app: Any, then: Any = None) -> int:
    app.run()
    if app.return_code:  # an error inside the app: Textual has printed it
        return int(app.return_code)
    status = then() if then is not None else 0
    folder = getattr(app, "session_dir", None)
    if folder is not None:
        acq = getattr(app, "acq", None)  # closed by now: its results include the open descent
        n = len(acq.results()) if acq is not None else len(getattr(app, "results", {}))
        print(
            f"session saved in {os.path.abspath(folder)} ({count(n, 'descent')}: raw.jsonl, "
            f"results.csv); replay it with: station replay {folder} --ui",
            file=sys.stderr,
            flush=True,
        )
    # Quit within a second: by now the raw log is closed, the results CSV and the
    # annotations are written and the simulator has ended; what is left is the interpreter
    # taking numpy, scipy and Textual apart (0.4-0.6 s), which nobody needs to wait for.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)
