"""Issue 19's figures in one run, each with its target and ratio: the results CSV's cost per
descent over a long recording, memory per descent, the UI's last impulse → fit on screen with
the comparison open, the replay's throughput against a bare loop, and the start-up of
``station fit`` against the bare import of its numerics.

Each figure comes from its own benchmark (day_2000.py, ui_fit_latency.py, replay_speed.py,
startup.py, fits_once.py for ``station annotate`` at 200 and at 2000 descents, in this
process and as typed), run here in turn; those say how they measure. On the shared 2-core
machine the absolute times follow its load (printed); the ratios are what to compare.

Run: python benchmarks/speed_table.py [--descents N] [--ui-descents N] [--repeats N]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import day_2000  # noqa: E402
import fits_once  # noqa: E402
import replay_speed  # noqa: E402
import startup  # noqa: E402
import ui_fit_latency  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--descents", type=int, default=2000, help="the recorded day's descents")
    ap.add_argument("--ui-descents", type=int, default=2000, help="descents through the UI")
    ap.add_argument("--repeats", type=int, default=10, help="start-up runs of each command")
    ap.add_argument("--annotate-sizes", default="200,2000",
                    help="the days annotated (descents; 'none': not measured)")  # fmt: skip
    args = ap.parse_args()
    rows: list[tuple[str, str, str, str]] = []
    start = time.perf_counter()
    loads = [os.getloadavg()[0]]

    day = day_2000.measure(args.descents)
    loads.append(os.getloadavg()[0])
    first = day["csv_ms"][1]
    for m, ms in day["csv_ms"].items():
        rows.append((f"results.csv write after descent {m}", f"{ms:.3f} ms",
                     "flat", f"{ms / first:.2f}× descent 1"))  # fmt: skip
    kb = day["kb_per_descent"]
    rows.append((f"memory per descent (200 → {args.descents})", f"{kb:.2f} kB", "≤ 2 kB",
                 f"{kb / 2:.2f}×"))  # fmt: skip
    rows.append(("replay reproduces the live results.csv", "byte for byte" if
                 day["replay_same"] else "DIFFERS", "byte for byte", ""))  # fmt: skip

    ui = ui_fit_latency.measure(args.ui_descents)
    loads.append(os.getloadavg()[0])
    n = args.ui_descents
    rows.append((f"UI: last impulse → fit on screen at descent {n}, comparison open",
                 f"{ui['median_end_ms']:.1f} ms (max {ui['max_end_ms']:.0f})", "≤ 50 ms",
                 f"{ui['median_end_ms'] / 50:.2f}×"))  # fmt: skip

    rates = replay_speed.measure_replay()
    loads.append(os.getloadavg()[0])
    bare = rates["bare loop"]
    for k in ("replay --no-fit", "parser alone"):
        rows.append((f"{k}, lines/s (bare loop {bare:,.0f})", f"{rates[k]:,.0f}",
                     "≥ 1/20 of the bare loop" if k.startswith("replay") else "",
                     f"1/{bare / rates[k]:.1f} of the bare loop"))  # fmt: skip

    times = startup.measure(args.repeats)
    loads.append(os.getloadavg()[0])
    fit, floor = statistics.median(times["fit"]), statistics.median(times["bare_fit"])
    rows.append(("start-up: station fit / import scipy.integrate, scipy.optimize",
                 f"{fit * 1e3:.0f} / {floor * 1e3:.0f} ms", "≤ 1.1×",
                 f"{fit / floor:.2f}×"))  # fmt: skip

    if args.annotate_sizes != "none":
        small, large = (int(x) for x in args.annotate_sizes.split(","))
        figs, pair = fits_once.annotate_figures([small, large], 3)
        loads.append(os.getloadavg()[0])
        for how, where in (("in place", "in the process"), ("as typed, in place", "as typed")):
            a, b = pair[how][small], pair[how][large]
            rows.append((f"station annotate {where}: {large} / {small} descents",
                         f"{b * 1e3:.0f} / {a * 1e3:.0f} ms", "≤ 1.5×",
                         f"{b / a:.2f}×"))  # fmt: skip
        for name in ("annotate, replayed, fits stored", "annotate as typed, replayed"):
            a, b = figs[small][name], figs[large][name]
            rows.append((f"(before, the day replayed: {name}: {large} / {small} descents)",
                         f"{b:.2f} / {a:.2f} s", "", f"{b / a:.2f}×"))  # fmt: skip

    print(f"issue 19's figures ({time.perf_counter() - start:.0f} s; load average "
          f"{min(loads):.1f}–{max(loads):.1f} on {os.cpu_count()} cores)")  # fmt: skip
    print()
    print("| figure | measured | target | ratio |")
    print("|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
