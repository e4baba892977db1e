"""What the season commands read from the store: the sessions with their conditions, the
descents for export, and each day's item effects for the comparison across days (pandas frames
where a table is what is wanted)."""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import sqlalchemy as sa

from station.errors import InputError
from station.store import schema
from station.store.db import Store

if TYPE_CHECKING:
    from station.model.season import SeasonDays

_OPS = ("<=", ">=", "!=", "==", "=", "<", ">")
_WHERE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|!=|==|=|<|>)\s*(.+?)\s*$")


@dataclass(frozen=True)
class Where:
    """One ``--where COND OP VALUE``: a day is selected when its condition satisfies it."""

    key: str
    op: str
    value: float | str

    def holds(self, v: float | str | None) -> bool:
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return False
        a, b = v, self.value
        if isinstance(b, str):
            a = str(a)
            return (a == b) if self.op in ("=", "==") else (a != b)
        assert isinstance(a, float)
        return {
            "<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b,
            "=": a == b, "==": a == b, "!=": a != b,
        }[self.op]  # fmt: skip


def parse_where(text: str) -> Where:
    """``snow_type=MF``, ``snow_temperature_c<-5`` (a decimal comma is a decimal point)."""
    from station.numbers import parse_number
    from station.session.records import METADATA_FIELDS, choice

    m = _WHERE.match(text)
    if not m:
        raise InputError(f"{text!r}: expected COND OP VALUE, e.g. snow_temperature_c<-5",
                         field="--where")  # fmt: skip
    key, op, value = m.groups()
    if key in schema.NUMERIC_CONDITIONS:
        try:
            return Where(key, op, parse_number(value))
        except ValueError as exc:
            raise InputError(f"{text!r}: {exc}", field="--where") from None
    if key in schema.TEXT_CONDITIONS:
        if op not in ("=", "==", "!="):
            raise InputError(f"{text!r}: {key} is a class: = or != only", field="--where")
        spec = next(f for f in METADATA_FIELDS if f.key == key)
        return Where(key, op, choice(value, spec.choices, "--where " + key))
    raise InputError(
        f"{text!r}: unknown condition {key!r} (one of {', '.join(schema.CONDITIONS)})",
        field="--where",
    )


def day_conditions(conn: sa.Connection) -> dict[str, dict[str, Any]]:
    """Each session's conditions: the mean of its descents' values (numbers), the value most
    descents have (classes); None where no descent has one."""
    c = schema.conditions
    per: dict[str, dict[str, list[Any]]] = {}
    for row in conn.execute(sa.select(c)).mappings():
        d = per.setdefault(row["session_id"], {k: [] for k in schema.CONDITIONS})
        for k in schema.CONDITIONS:
            if row[k] is not None:
                d[k].append(row[k])
    out: dict[str, dict[str, Any]] = {}
    for sid, vals in per.items():
        o: dict[str, Any] = {}
        for k in schema.NUMERIC_CONDITIONS:
            o[k] = float(np.mean(vals[k])) if vals[k] else None
        for k in schema.TEXT_CONDITIONS:
            o[k] = Counter(vals[k]).most_common(1)[0][0] if vals[k] else None
        out[sid] = o
    return out


def list_sessions(store: Store) -> list[dict[str, Any]]:
    """One row per session, oldest first: date, site, descents, items, conditions."""
    s, d = schema.sessions, schema.descents
    with store.reading() as conn:
        conds = day_conditions(conn)
        items: dict[str, list[str]] = {}
        q = (
            sa.select(d.c.session_id, d.c.item)
            .where(d.c.descent_status != "aborted")
            .order_by(d.c.session_id, d.c.number)
        )
        for sid, item in conn.execute(q):
            lst = items.setdefault(sid, [])
            if item not in lst:
                lst.append(item)
        rows = conn.execute(sa.select(s).order_by(s.c.started, s.c.name)).mappings().all()
    out = []
    for r in rows:
        out.append(
            {
                "session": r["name"],
                "id": r["id"],
                "date": r["date"],
                "started": r["started"],
                "site": r["site"],
                "descents": r["descents"],
                "valid": r["valid"],
                "items": items.get(r["id"], []),
                **conds.get(r["id"], dict.fromkeys(schema.CONDITIONS)),
            }
        )
    return out


#: the columns of ``season export``, in order
EXPORT_COLUMNS = [
    "session", "date", "site", "descent", "start_time", "status", "descent_status",
    "invalid_reason", "item", *schema.ITEM_PARTS, *schema.CONDITIONS,
    "mu", "mu_lo", "mu_hi", "mu1", "cda", "cda_lo", "cda_hi", "v0", "v0_lo", "v0_hi",
    "rms_residual_ms", "mass_kg", "air_density", "gravity", "model", "flags", "notes",
    "session_id",
]  # fmt: skip


def export_frame(store: Store) -> Any:
    """One row per descent with its session, conditions, item and fit (a pandas DataFrame)."""
    import pandas as pd  # type: ignore[import-untyped]

    s, d, c = schema.sessions, schema.descents, schema.conditions
    q = (
        sa.select(
            s.c.name.label("session"),
            s.c.date,
            s.c.site,
            s.c.id.label("session_id"),
            *[col for col in d.c if col.name != "session_id"],
            *[c.c[k] for k in schema.CONDITIONS],
        )  # fmt: skip
        .select_from(
            s.join(d, d.c.session_id == s.c.id).outerjoin(
                c, sa.and_(c.c.session_id == d.c.session_id, c.c.descent == d.c.number)
            )
        )
        .order_by(s.c.started, s.c.name, d.c.number)
    )
    with store.reading() as conn:
        rows = conn.execute(q).mappings().all()
    frame = pd.DataFrame([dict(r) for r in rows], columns=EXPORT_COLUMNS + ["number"])
    frame["descent"] = frame.pop("number")
    return frame[EXPORT_COLUMNS]


@dataclass(frozen=True)
class _DayFits:
    """What the store holds of every day's fits for one grouping (``by``)."""

    conditions: dict[str, dict[str, Any]]  # by session id
    names: dict[str, str]  # session id -> name, oldest first
    fits: dict[str, Any]
    items: dict[str, list[Any]]
    covariances: dict[str, list[Any]]
    #: the items with a descent a day fit could take (valid, enough photocells), per day
    tested: dict[str, set[str]]


def _day_fits(store: Store, by: str) -> _DayFits:
    from station.model.compare import DAY_FIT_MIN_PHOTOCELLS, DAY_FIT_STATUSES

    s, f, it, cv = schema.sessions, schema.day_fits, schema.items, schema.item_covariance
    d = schema.descents
    with store.reading() as conn:
        conds = day_conditions(conn)
        names = dict(
            conn.execute(sa.select(s.c.id, s.c.name).order_by(s.c.started, s.c.name)).all()
        )  # noqa: E501
        fits = {r.session_id: r for r in conn.execute(sa.select(f).where(f.c.grouping == by))}
        items: dict[str, list[Any]] = {}
        for r in conn.execute(sa.select(it).where(it.c.grouping == by).order_by(it.c.position)):
            items.setdefault(r.session_id, []).append(r)
        covs: dict[str, list[Any]] = {}
        for r in conn.execute(sa.select(cv).where(cv.c.grouping == by)):
            covs.setdefault(r.session_id, []).append(r)
        # the descents a day fit could take (collect()'s own rule, its constants): an item
        # with one of them on a day is not among its items, and was left out without a word
        label = d.c.item if by == "item" else d.c[by]
        valid = (
            sa.select(d.c.session_id, label.label("label"))
            .where(d.c.invalid_reason == "", d.c.status.in_(DAY_FIT_STATUSES))
            .where(d.c.photocells_used >= DAY_FIT_MIN_PHOTOCELLS)
        )
        tested: dict[str, set[str]] = {}
        for r in conn.execute(valid):
            tested.setdefault(r.session_id, set()).add(r.label.strip() or f"(no {by})")
    return _DayFits(conds, names, fits, items, covs, tested)


def day_effects(store: Store, by: str, where: list[Where] | None = None) -> SeasonDays:
    """Each selected day's item effects for ``by`` (:class:`station.model.season.DayEffects`),
    the days left out with why, and every day's conditions (by session name)."""
    from station.model.season import DayEffects, SeasonDays

    stored = _day_fits(store, by)
    left_out: list[str] = []
    single: dict[str, list[str]] = {}  # item → the days it had one valid descent on
    out: list[DayEffects] = []
    for sid, name in stored.names.items():
        cond = stored.conditions.get(sid, dict.fromkeys(schema.CONDITIONS))
        if where and not all(w.holds(cond.get(w.key)) for w in where):
            continue
        fit = stored.fits.get(sid)
        if fit is None:
            left_out.append(f"{name}: no day fit stored (station season add it again)")
            continue
        if fit.status == "one-item":
            continue
        if fit.status != "ok":
            left_out.append(f"{name}: its day fit is {fit.status}" + (
                f" ({fit.message})" if fit.message else ""))  # fmt: skip
            continue
        rows = stored.items.get(sid, [])
        for x in stored.tested.get(sid, set()) - {r.item for r in rows}:
            single.setdefault(x, []).append(name)
        if len(rows) < 2:
            continue
        k = len(rows)
        cov = np.zeros((k, k))
        for r in stored.covariances.get(sid, []):
            if r.a < k and r.b < k:
                cov[r.a, r.b] = cov[r.b, r.a] = r.cov
        numeric = {key: cond[key] for key in schema.NUMERIC_CONDITIONS if cond.get(key) is not None}
        out.append(
            DayEffects(
                day=name,
                items=tuple(r.item for r in rows),
                mu=np.array([r.mu for r in rows]),
                cov=cov,
                descents=tuple(r.descents for r in rows),
                conditions=numeric,
            )
        )
    kept = {x for day in out for x in day.items}
    gone = sorted(x for x in single if x not in kept)
    if gone:
        on = "; ".join(f"{x} on {', '.join(single[x])}" for x in gone)
        left_out.append(
            f"{len(gone)} {by}(s) with one valid descent a day, too few to compare ({on}): "
            "one descent's glide cannot be told from its posture"
        )
    names = stored.names
    named = {names[sid]: cond for sid, cond in stored.conditions.items() if sid in names}
    return SeasonDays(out, left_out, named)
