"""``station live`` and ``demo`` (and ``replay --ui``): the trackside terminal UI."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from station.cli.common import (
    _date,
    _positive,
)
from station.errors import InputError


def _replay_ui(args: argparse.Namespace) -> int:
    from station.cli.recording import _replay_config
    from station.session.replay import source_date
    from station.ui.app import StationApp

    cfg = _replay_config(args)  # a wrong source or config is said first, terminal or not
    require_terminal("replay --ui", "without --ui, replay prints the results")
    date = source_date(args.source, _date(args.date))
    speed = None if args.fast else args.speed
    app = StationApp(cfg, mode="replay", source=args.source, speed=speed, date=date)
    return _run_ui(app, then=lambda: _save_kept(app))


def _save_kept(app: Any) -> int:
    """What the engineer entered while replaying a session, saved in it as ``station annotate``
    saves it (results.csv rewritten unless a recorder owns it): a replay records nothing, and
    a mark that vanished at quit would be a result silently different from the one seen."""
    if not app.kept:
        return 0
    from station.cli.analysis import save_annotations

    try:
        said = save_annotations(app.source, app.kept)
    except InputError as exc:
        print(f"station replay: error: what was entered is not saved: {exc}", file=sys.stderr)
        return 2
    print(said, file=sys.stderr, flush=True)
    return 0


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


def _run_ui(app: Any, then: Any = None) -> int:
    app.run()
    if app.return_code:  # an error inside the app: Textual has printed it
        return int(app.return_code)
    status = then() if then is not None else 0
    folder = getattr(app, "session_dir", None)
    if folder is not None:
        from station.report.text import count

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


def cmd_live(args: argparse.Namespace) -> int:
    from station.session import store as sessions
    from station.session.config import load_config
    from station.session.ports import check_port
    from station.ui.app import StationApp

    cfg = load_config(args.config)
    check_port(cfg.serial.port, args.config)  # a wrong port: say so and list them, at once
    require_terminal("live", "to record without a terminal: station record")
    folder = args.session_dir or sessions.default_dir()
    return _run_ui(StationApp(cfg, mode="live", session_dir=folder))


DEMO_SKIS = [("demo pair A", 0.0080), ("demo pair B", 0.0095), ("demo pair C", 0.0110)]


def demo_config_path() -> str:
    """The bundled demo station config (package data, so it works without a checkout)."""
    from importlib.resources import files

    return str(files("surveys") / "demo_station.yaml")


def cmd_demo(args: argparse.Namespace) -> int:
    import random
    import tempfile

    from station.session import store as sessions
    from station.session.config import load_config
    from station.ui.app import StationApp

    require_terminal("demo", "the simulated timer alone: station-sim")
    cfg = load_config(demo_config_path())
    folder = args.session_dir or sessions.default_dir("sessions").replace(
        os.sep + "20", os.sep + "demo-20", 1
    )
    link = os.path.join(tempfile.mkdtemp(prefix="station-demo-"), "timer")
    # the simulated timer runs as a process of its own, as a real timer would
    sim = [
        sys.executable, "-m", "simulators.timer", "--survey", cfg.survey_path, "--link", link,
        "--descents", "100000", "--interval", str(args.interval), "--first-after", "3",
        "--speed", str(args.speed), "--skis", ",".join(f"{mu}" for _n, mu in DEMO_SKIS),
        "--seed", str(args.seed if args.seed is not None else random.randrange(1 << 30)),
        "--noise-ms", "0.3", "--double-trigger", "0.05", "--hold", "0",
        "--air-density", f"{cfg.air_density}", "--mass", f"{cfg.mass_kg}",
    ]  # fmt: skip
    app = StationApp(
        cfg,
        mode="demo",
        session_dir=folder,
        sim_command=sim,
        demo_skis=[n for n, _mu in DEMO_SKIS],
    )
    return _run_ui(app)


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("live", help="the trackside terminal UI on a timer")
    p.add_argument("--config", required=True, help="station config YAML")
    p.add_argument("--session-dir", metavar="DIR", help="default: sessions/DATE_TIME")
    p.set_defaults(func=cmd_live)

    p = sub.add_parser("demo", help="the terminal UI on a simulated timer and the demo run")
    p.add_argument("--session-dir", metavar="DIR", help="default: sessions/demo-DATE_TIME")
    p.add_argument("--interval", type=_positive, default=20.0, help="seconds between descents")
    p.add_argument("--speed", type=_positive, default=1.0, help="run the timer's clock faster")
    p.add_argument("--seed", type=int, help="seed of the simulated descents")
    p.set_defaults(func=cmd_demo)
