"""``station live`` and ``demo`` (and ``replay --ui``): the trackside terminal UI."""

from __future__ import annotations

import argparse
import os
import random
import re
import sys
import tempfile
from importlib.resources import files
from typing import Any

from station.cli.common import _positive


def cmd_live(args: argparse.Namespace) -> int:
    # here, not at the top: the UI, numpy and scipy (see station/cli/tui.py and recording.py)
    from station.cli.tui import require_terminal, run_ui
    from station.session import folder as sessions
    from station.session.configcheck import checked_config
    from station.session.ports import check_port
    from station.ui.app import StationApp

    cfg = checked_config(args.config)  # config, survey and photocells, as station check does
    check_port(cfg.serial.port, args.config)  # then a wrong port: say so and list them
    folder = args.session_dir or sessions.default_dir()
    sessions.check_new(folder)  # said in one line here, not as a traceback inside the UI
    require_terminal("live", "to record without a terminal: station record")
    status = run_ui(StationApp(cfg, mode="live", session_dir=folder))
    if sessions.is_session(folder):
        from station.cli.console import add_after

        add_after(folder, cfg.store)  # when a season store is configured
    return status


DEMO_SKIS = [("demo pair A", 0.0080), ("demo pair B", 0.0095), ("demo pair C", 0.0110)]


def demo_config_path() -> str:
    """The bundled demo station config (package data, so it works without a checkout)."""
    return str(files("station.surveys") / "demo_station.yaml")


def demo_config(link: str) -> Any:
    """The demo config with its port the simulated timer's pty (``link``, made when the demo
    starts): the session's copy of the config, and so its raw log's first record, then name the
    port the demo opened, not the bundled config's ``/tmp/station-timer``, which it never did."""
    from dataclasses import replace

    from station.session.config import load_config

    cfg = load_config(demo_config_path())
    # the session's config is a copy of the text: the port is changed there too (the bundled
    # file's shape is tested: tests/test_cli.py)
    text = re.sub(r"(?m)^(\s+port:\s*)\S+", lambda m: m.group(1) + link, cfg.text, count=1)
    return replace(cfg, text=text, serial=replace(cfg.serial, port=link))


def cmd_demo(args: argparse.Namespace) -> int:
    # here, not at the top: the UI, numpy and scipy (see station/cli/tui.py and recording.py)
    from station.cli.tui import require_terminal, run_ui
    from station.session import folder as sessions
    from station.ui.app import StationApp

    folder = args.session_dir or sessions.default_dir("sessions").replace(
        os.sep + "20", os.sep + "demo-20", 1
    )
    sessions.check_new(folder)  # said in one line here, not as a traceback inside the UI
    require_terminal("demo", "the simulated timer alone: station-sim")
    link = os.path.join(tempfile.mkdtemp(prefix="station-demo-"), "timer")
    cfg = demo_config(link)
    # the simulated timer runs as a process of its own, as a real timer would
    sim = [
        sys.executable, "-m", "station.simulators.timer", "--survey", cfg.survey_path,
        "--link", link, "--descents", "100000", "--interval", str(args.interval),
        "--first-after", "3",
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
    return run_ui(app)


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
