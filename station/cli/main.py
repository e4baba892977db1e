"""The ``station`` command line: the parser of every subcommand, and the one place that turns
bad input into one line on stderr and exit status 2, never a traceback.

Each group of subcommands lives in its own module and is imported only when the parser is
built; the work a command does is imported inside the command, so ``station fit`` does not load
pandas, the serial port or the terminal UI.
"""

from __future__ import annotations

import argparse
import os
import sys

from station import __version__
from station.cli import (
    analysis,
    common,
    memory,
    ports,
    recording,
    report,
    sessions,
    survey,
    terminal,
)
from station.errors import InputError


def build_parser() -> argparse.ArgumentParser:
    ap = common._Parser(
        prog="station",
        description="Measurement station for ski-friction test days "
        "(Kaps, Nachbauer & Mössner 1996).",
    )
    ap.add_argument("--version", action="version", version=f"station {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=common._Parser)
    for group in (survey, recording, analysis, terminal, sessions, ports, memory, report):
        group.add_parsers(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return common.dispatch(args)
    except InputError as exc:
        print(f"station: error: {exc}", file=sys.stderr)
        return common.EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # the reader went away (`station fit … | head`): stop quietly, as other tools do
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141


if __name__ == "__main__":
    raise SystemExit(main())
