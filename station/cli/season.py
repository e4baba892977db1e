"""``station season``: every test day in one store, and its items compared across days.

``add`` puts session folders into the store (one transaction each, idempotent), ``list`` shows
them, ``export`` writes one row per descent for R and spreadsheets, ``compare`` compares the
items across days (:mod:`station.model.season`), ``report`` draws it on one HTML page, and
``push`` sends a station's store to a team's server. The store is ``--store PATH_OR_URL``, else
``$STATION_STORE``, else ``sessions/season.db``.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING, Any

from station.cli.common import _print_json, _warn, open_output, output_path
from station.errors import InputError

if TYPE_CHECKING:
    from station.model.season import SeasonComparison, SeasonResult


def _open(args: argparse.Namespace, create: bool = False) -> Any:
    from station.store.db import open_store, resolve

    target = resolve(args.store)
    return open_store(target, create=create, say=lambda m: print(m, file=sys.stderr))


def add_sessions(store: Any, sessions: list[str], out: Any = print) -> int:
    """Add each session, one line each; returns the exit status (2 when one was refused).
    A database error (the server gone) ends the batch: the sessions after it are not tried,
    and nothing of the one being added is left half-written (its transaction rolls back)."""
    import sqlalchemy as sa

    from station.store.db import database_error
    from station.store.writer import add_session

    status = 0
    for k, session in enumerate(sessions):
        try:
            verdict = add_session(store, session)
        except InputError as exc:
            why = exc.message if exc.path == session else str(exc)
            print(f"{session}: refused: {why}", file=sys.stderr)
            status = 2
            continue
        except sa.exc.SQLAlchemyError as exc:
            rest = len(sessions) - k - 1
            tail = f"; the {rest} session(s) after it not tried" if rest else ""
            print(f"{session}: not added: {database_error(exc, store.where)}{tail} "
                  "(add them again: what is stored is whole)", file=sys.stderr)  # fmt: skip
            return 2
        out(f"{session}: {verdict}")
    return status


def cmd_add(args: argparse.Namespace) -> int:
    store = _open(args, create=True)
    try:
        return add_sessions(store, args.sessions)
    finally:
        store.close()


def _cond(v: Any, spec: str = "g") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    return format(v, spec) if isinstance(v, float) else str(v)


def cmd_list(args: argparse.Namespace) -> int:
    from station.store.queries import list_sessions

    store = _open(args)
    try:
        rows = list_sessions(store)
    finally:
        store.close()
    if args.json:
        _print_json({"sessions": rows})
        return 0
    if not rows:
        print(f"no sessions in {store.where}")
        return 0
    w = max(len("session"), *(len(r["session"]) for r in rows))
    # the site in full up to 40 characters ("Demo run (simula" told nobody which run it was)
    ws = min(40, max(len("site"), *(len(r["site"] or "") for r in rows)))
    print(f"{'session':<{w}}  {'date':<10}  {'site':<{ws}}  {'descents':>8}  {'valid':>5}  "
          f"{'snow °C':>7}  {'air °C':>6}  {'snow':<4}  items")  # fmt: skip
    for r in rows:
        snow = "/".join(x for x in (r["snow_type"], r["wetness"]) if x) or "—"
        print(f"{r['session']:<{w}}  {r['date'] or '—':<10}  {_cut(r['site'] or '—', ws):<{ws}}  "
              f"{r['descents']:>8}  {r['valid']:>5}  {_cond(r['snow_temperature_c'], '.1f'):>7}  "
              f"{_cond(r['air_temperature_c'], '.1f'):>6}  {snow:<4}  "
              f"{'; '.join(r['items']) or '—'}")  # fmt: skip
    return 0


def _cut(text: str, width: int) -> str:
    """``text`` in ``width`` characters, an ellipsis where it was cut."""
    return text if len(text) <= width else text[: width - 1] + "…"


def cmd_export(args: argparse.Namespace) -> int:
    from station.csvfiles import safe_text  # the one CSV policy
    from station.store.queries import export_frame

    output_path(args.csv, "--csv")
    store = _open(args)
    try:
        frame = export_frame(store)
    finally:
        store.close()
    for col in frame.columns:
        if frame[col].dtype == object:
            frame[col] = frame[col].map(safe_text)
    with open_output(args.csv, "--csv") as fh:
        frame.to_csv(fh, index=False, lineterminator="\n")
    if args.csv != "-":
        print(f"{len(frame)} descent(s) written to {args.csv}", file=sys.stderr)
    return 0


def _at(texts: list[str]) -> dict[str, float]:
    from station.numbers import parse_number
    from station.store.schema import NUMERIC_CONDITIONS

    out: dict[str, float] = {}
    for text in texts:
        key, sep, value = text.partition("=")
        key = key.strip()
        if not sep or key not in NUMERIC_CONDITIONS:
            raise InputError(
                f"{text!r}: expected COND=VALUE with COND one of {', '.join(NUMERIC_CONDITIONS)}",
                field="--at",
            )
        try:
            out[key] = parse_number(value.strip())
        except ValueError as exc:
            raise InputError(f"{text!r}: {exc}", field="--at") from None
    return out


def season_comparison(args: argparse.Namespace, store: Any) -> SeasonComparison:
    """The comparison ``compare`` and ``report`` show, and the days it joined."""
    from station.cli.common import unique_prefix
    from station.model.season import SeasonError
    from station.store.queries import day_effects, parse_where

    where = [parse_where(w) for w in args.where or []]
    at = _at(args.at or [])
    selected = day_effects(store, args.by, where)
    if not selected.days:
        raise InputError(
            f"no day in {store.where} compares two {args.by}s or more"
            + (" where " + " and ".join(args.where) if args.where else ""),
        )
    reference = args.reference
    if reference is not None:
        reference = unique_prefix(reference, selected.item_names(), args.by, "--reference")
    try:
        return selected.compare(reference, at)
    except SeasonError as exc:
        raise InputError(str(exc)) from None


def cmd_compare(args: argparse.Namespace) -> int:
    store = _open(args)
    try:
        res = season_comparison(args, store).result
    finally:
        store.close()
    if args.json:
        _print_json(
            {
                "reference": res.reference,
                "by": args.by,
                "at": res.at,
                "items": [it.to_dict() for it in res.ranked()],
                "heterogeneity": res.heterogeneity(),
                "days": res.days,
                "descents": res.descents,
                "listed_days": res.listed_days,
                "listed_descents": res.listed_descents,
                "warnings": res.warnings,
            }
        )
        return 0
    print(format_season(res, args.by))
    for w in res.warnings:
        _warn(w)
    return 0


def format_season(res: SeasonResult, by: str) -> str:
    at = ", ".join(f"{k}={v:g}" for k, v in res.at.items())
    lines = [
        f"season comparison by {by}: {res.counts()}, against {res.reference}"
        + (f", at {at}" if at else ""),
        f"between-day heterogeneity: τ {res.tau:.5f} (SD of a difference from day to day "
        f"beyond {'the conditions given' if at else 'the within-day uncertainty'}; Q "
        f"{res.q:.1f} on {res.dof} dof"
        + (f", p = {res.q_p:.2g})" if res.q_p is not None else ")"),  # fmt: skip
        "",
    ]
    w = min(28, max([6, *(len(i.item) + 2 for i in res.items)]))
    lines.append(f"{'rank':<5}{'item':<{w}}{'days':>5}{'descents':>9}{'Δμ':>10}   "
                 f"{'90 % CI':<22}{'P(faster)':>9}{'P(best)':>9}")  # fmt: skip
    for k, it in enumerate(res.ranked(), start=1):
        if it.delta_mu is None or it.ci90 is None:
            lines.append(f"{'—':<5}{it.item:<{w}}{it.days:>5}{it.descents:>9}   {it.note}")
            continue
        ci = f"[{it.ci90[0]:+.5f}, {it.ci90[1]:+.5f}]" if it.item != res.reference else "reference"
        pf = f"{it.p_faster:.3f}" if it.p_faster is not None else "—"
        pb = f"{it.p_best:.3f}" if it.p_best is not None else "—"
        lines.append(f"{k:<5}{it.item:<{w}}{it.days:>5}{it.descents:>9}{it.delta_mu:>+10.5f}   "
                     f"{ci:<22}{pf:>9}{pb:>9}")  # fmt: skip
        for c, (s, (lo, hi)) in it.slopes.items():
            lines.append(f"{'':<5}  slope in {c}: {s:+.2e} per unit [{lo:+.2e}, {hi:+.2e}]")
    return "\n".join(lines)


def cmd_push(args: argparse.Namespace) -> int:
    import sqlalchemy as sa

    from station.store import schema
    from station.store.db import database_error, open_store, safe_url
    from station.store.writer import load_record, stored_content, write_record

    local = _open(args)
    try:
        remote = open_store(args.to, create=True, say=lambda m: print(m, file=sys.stderr))
    except BaseException:
        local.close()
        raise
    counts: dict[str, int] = {}
    try:
        with local.reading() as conn:
            t = schema.sessions
            ids = list(conn.execute(sa.select(t.c.id, t.c.content_sha256).order_by(t.c.started)))
        for sid, content in ids:
            try:
                with remote.reading() as rc:
                    if stored_content(rc, sid) == content:
                        counts["unchanged"] = counts.get("unchanged", 0) + 1
                        continue
                with local.reading() as conn:
                    rec = load_record(conn, sid)
                with remote.writing() as rc:
                    verdict = write_record(rc, rec)
            except sa.exc.SQLAlchemyError as exc:
                done = sum(counts.values())
                print(f"{safe_url(args.to)}: push stopped after {done} of {len(ids)} sessions: "
                      f"{database_error(exc, remote.where).message} (push again: it goes on "
                      "where it stopped)", file=sys.stderr)  # fmt: skip
                return 2
            counts[verdict] = counts.get(verdict, 0) + 1
    finally:
        local.close()
        remote.close()
    said = ", ".join(f"{n} {k}" for k, n in counts.items()) or "nothing to push"
    print(f"{len(ids)} session(s) pushed to {safe_url(args.to)}: {said}")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from station.cli.common import output_dir
    from station.report.season_report import write_season_report

    folder = output_dir(args.out, "--out")
    store = _open(args)
    try:
        season = season_comparison(args, store)
    finally:
        store.close()
    days = season.selected
    path = write_season_report(folder, season.result, days.days, days.conditions, args.by)
    print(f"season report: {path}", file=sys.stderr)
    return 0


def _store_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--store", metavar="PATH_OR_URL",
                   help="the season store: an SQLite file or postgresql://user@host/db "
                        "(default $STATION_STORE, else sessions/season.db)")  # fmt: skip


def _compare_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--by", choices=["item", "ski", "wax", "grind"], default="item",
                   help="what to compare: items (ski / wax), skis, waxes or grinds")  # fmt: skip
    p.add_argument("--reference", metavar="NAME", help="compare every other with this one")
    p.add_argument("--at", action="append", metavar="COND=VALUE",
                   help="the effects at this condition, each linear in it (e.g. "
                        "snow_temperature_c=-12); may be repeated")  # fmt: skip
    p.add_argument("--where", action="append", metavar="COND OP VALUE",
                   help="only the days whose condition holds (snow_type=MF, "
                        "snow_temperature_c<-5); may be repeated")  # fmt: skip


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("season", help="the season store: add days, list, export, compare across "
                                      "days, report, push")  # fmt: skip
    ssub = p.add_subparsers(
        dest="season_command",
        required=True,
        parser_class=type(p),
        metavar="{add,list,compare,export,report,push}",
        help="what to do with the store",
    )

    q = ssub.add_parser("add", help="add or update session folders in the store")
    q.add_argument("sessions", nargs="+", metavar="SESSION", help="session folders")
    _store_option(q)
    q.set_defaults(func=cmd_add)

    q = ssub.add_parser("list", help="the stored sessions: date, site, descents, items, snow")
    _store_option(q)
    q.add_argument("--json", action="store_true", help="machine-readable output")
    q.set_defaults(func=cmd_list)

    q = ssub.add_parser("export", help="one row per descent: session, conditions, item, fit")
    _store_option(q)
    q.add_argument("--csv", required=True, metavar="FILE", help="the CSV file; - = stdout")
    q.set_defaults(func=cmd_export)

    q = ssub.add_parser("compare", help="items compared across days (a network of the days)")
    _store_option(q)
    _compare_options(q)
    q.add_argument("--json", action="store_true", help="machine-readable output")
    q.set_defaults(func=cmd_compare)

    q = ssub.add_parser("report", help="one self-contained HTML page of the season")
    _store_option(q)
    _compare_options(q)
    q.add_argument("--out", required=True, metavar="DIR", help="folder for season.html")
    q.set_defaults(func=cmd_report)

    q = ssub.add_parser("push", help="send this store's sessions to a team's server")
    _store_option(q)
    q.add_argument("--to", required=True, metavar="URL", help="postgresql://user@host/db")
    q.set_defaults(func=cmd_push)
