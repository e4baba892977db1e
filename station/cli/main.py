"""The ``station`` command line: the parser of every subcommand, and the one place that turns
bad input into one line on stderr and exit status 2, never a traceback.

Each group of subcommands lives in its own module. A command line that names a command builds
(and imports) only that command's group; ``station --help`` or an unknown command builds them
all. The work a command does is imported inside the command, so ``station fit`` does not load
the typed session records, the serial port or the terminal UI.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys

from station import __version__
from station.cli import common
from station.errors import InputError

#: every command and the module (station.cli.<module>) that defines it, in the order of --help
COMMANDS = {
    "survey": "survey", "simulate": "fit", "fit": "fit", "fit-traverse": "fit",
    "check": "check", "record": "recording", "replay": "recording", "export": "recording",
    "annotate": "analysis", "compare": "analysis",
    "live": "terminal", "demo": "terminal",
    "sessions": "sessions", "ports": "ports", "import": "memory", "report": "report",
    "season": "season", "plan": "plan",
}  # fmt: skip


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or of ``command``'s group only (what its run needs)."""
    ap = common._Parser(
        prog="station",
        description="Measurement station for ski-friction test days "
        "(Kaps, Nachbauer & Mössner 1996).",
    )
    ap.add_argument("--version", action="version", version=f"station {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, parser_class=common._Parser)
    groups = [COMMANDS[command]] if command in COMMANDS else list(dict.fromkeys(COMMANDS.values()))
    for name in groups:
        importlib.import_module(f"station.cli.{name}").add_parsers(sub)
    return ap


def one_blas_thread() -> None:
    """Cap OpenBLAS at one thread for this process, unless the user chose a number.

    The station's matrices are small (a spline's 70 × 70, a fit's 9 × 4): a pool of BLAS
    threads gains nothing on them, and on a busy machine (the terminal UI and its fit worker, a
    shared laptop) each threaded LAPACK call waits for a busy core, while the idle pool spins
    beside the imports. Measured on a loaded 2-core machine: the spline's one 68 × 68 eigh in
    ``station fit`` took 70-90 ms in two runs of three, 0.5 ms with one thread; importing numpy
    and scipy took 0.83 s of CPU with the pool, 0.72 s without. (``station compare`` caps its
    joint fit the same way, with threadpoolctl, for the same reason.) OpenBLAS reads the
    variable once, when numpy loads, so this runs before any command imports numpy; in a
    process that already has numpy (tests calling :func:`main`) it does nothing.
    """
    if "numpy" in sys.modules:
        return
    if not any(
        v in os.environ for v in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")
    ):
        os.environ["OPENBLAS_NUM_THREADS"] = "1"


#: commands that do one bounded piece of work and end (one descent's fit): the garbage
#: collector stays off while they run. Most of their time is importing numpy and scipy, which
#: allocates hundreds of thousands of objects and no garbage worth collecting; the collections
#: it triggers cost some 8 % of that import's CPU (12 paired runs of the bare import on the
#: shared 2-core machine: 0.80 s with the collector, 0.73 s without). Every other command
#: (recording, the UI, replays of whole days) runs with the collector as Python sets it.
GC_OFF_COMMANDS = frozenset({"fit", "fit-traverse"})


def main(argv: list[str] | None = None) -> int:
    one_blas_thread()
    words = sys.argv[1:] if argv is None else argv
    gc_off = bool(words) and words[0] in GC_OFF_COMMANDS and gc.isenabled()
    if gc_off:
        gc.disable()
    try:
        return _run(words, argv)
    finally:
        if gc_off:  # a caller in the same process (the tests) gets its collector back
            gc.enable()


def _run(words: list[str], argv: list[str] | None) -> int:
    args = build_parser(words[0] if words else None).parse_args(argv)
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
