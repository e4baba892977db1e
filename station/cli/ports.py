"""``station ports``: the serial ports of this machine with their descriptions, to find the
timer's USB-serial adapter (README, "Connecting the timer")."""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import asdict
from typing import Any

from station.cli.common import _print_json


def cmd_ports(args: argparse.Namespace) -> int:
    from station.session.ports import DIALOUT_HINT, list_serial_ports

    ports = list_serial_ports()
    if args.json:
        _print_json(
            [asdict(p) | {"accessible": os.access(p.device, os.R_OK | os.W_OK)} for p in ports]
        )
        return 0
    if not ports:
        print("no serial port found: plug in the timer's USB-serial adapter and try again")
        return 0
    width = max(len(p.device) for p in ports)
    denied = []
    for p in ports:
        ok = os.access(p.device, os.R_OK | os.W_OK)
        if not ok:
            denied.append(p.device)
        print(f"{p.line().replace(p.device, p.device.ljust(width), 1)}"
              + ("" if ok else "  [no permission]"))  # fmt: skip
    if denied and sys.platform.startswith("linux"):
        print(f"no permission for {', '.join(denied)}: {DIALOUT_HINT}", file=sys.stderr)
    return 0


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("ports", help="list the serial ports, to find the timer")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_ports)
