"""Adding a session to the store: one transaction per session, idempotent.

The session's row is written with ``INSERT … ON CONFLICT DO UPDATE`` on its id (the raw log's
SHA-256), so the database, not a check in the client, keeps one row per session when several
stations add at once; the upsert also locks that row, so whatever else the session brings is
replaced (deleted and inserted again) by one writer at a time. A failure anywhere (a damaged
row, the server going away) rolls the whole session back: the next add completes it.
Values go to the database as parameters, never formatted into SQL: a note with quotes or SQL
in it is stored verbatim.
"""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa

from station.store import schema
from station.store.db import Store
from station.store.ingest import Identity, SessionRecord, identify, read

#: what a session's add did
ADDED, UPDATED, UNCHANGED = "added", "updated", "unchanged"


def _upsert(conn: sa.Connection, row: dict[str, Any]) -> None:
    table = schema.sessions
    from sqlalchemy.dialects import postgresql, sqlite

    dialect = postgresql if conn.dialect.name == "postgresql" else sqlite
    stmt = dialect.insert(table).values(**row)
    keep = {"id", "added_t"}
    stmt = stmt.on_conflict_do_update(
        index_elements=[table.c.id],
        set_={c.name: stmt.excluded[c.name] for c in table.columns if c.name not in keep},
    )
    conn.execute(stmt)


def stored_content(conn: sa.Connection, session_id: str) -> str | None:
    """The stored session's content digest, or None when it is not stored."""
    t = schema.sessions
    return conn.execute(sa.select(t.c.content_sha256).where(t.c.id == session_id)).scalar()


def write_record(conn: sa.Connection, rec: SessionRecord) -> str:
    """Write one session's rows in the caller's transaction; returns added/updated/unchanged.

    On PostgreSQL the session's id is locked for the transaction first (an advisory lock: a
    row lock cannot hold a row not yet there), so two stations adding the same day at once
    take turns and the second sees the first's rows: one says "added", the other "unchanged"
    (both said "added" before, the rows whole either way). SQLite's writers take turns
    already (BEGIN IMMEDIATE)."""
    if conn.dialect.name == "postgresql":
        conn.execute(
            sa.text("SELECT pg_advisory_xact_lock(hashtextextended(:id, 0))"),
            {"id": rec.identity.id},
        )
    before = stored_content(conn, rec.identity.id)
    if before == rec.identity.content_sha256:
        return UNCHANGED
    _upsert(conn, rec.session)
    sid = rec.identity.id
    for table in schema.CHILDREN:
        conn.execute(sa.delete(table).where(table.c.session_id == sid))
    for table, rows in (
        (schema.descents, rec.descents),
        (schema.annotation_log, rec.annotations),
        (schema.conditions, rec.conditions),
        (schema.day_fits, rec.day_fits),
        (schema.items, rec.items),
        (schema.item_covariance, rec.covariances),
    ):
        if rows:
            conn.execute(sa.insert(table), rows)
    return ADDED if before is None else UPDATED


def add_session(store: Store, session: str) -> str:
    """Add or update one session folder (:class:`InputError` when it cannot be read)."""
    ident: Identity = identify(session)
    with store.reading() as conn:
        if stored_content(conn, ident.id) == ident.content_sha256:
            return UNCHANGED
    rec = read(session, ident)
    with store.writing() as conn:
        return write_record(conn, rec)


def load_record(conn: sa.Connection, session_id: str) -> SessionRecord:
    """A stored session's rows, as :func:`write_record` takes them (``season push``)."""
    t = schema.sessions
    row = conn.execute(sa.select(t).where(t.c.id == session_id)).mappings().one()
    rec = SessionRecord(Identity(session_id, row["content_sha256"]), dict(row))

    def rows(table: sa.Table) -> list[dict[str, Any]]:
        q = sa.select(table).where(table.c.session_id == session_id)
        return [dict(r) for r in conn.execute(q).mappings()]

    rec.descents = rows(schema.descents)
    rec.annotations = rows(schema.annotation_log)
    rec.conditions = rows(schema.conditions)
    rec.day_fits = rows(schema.day_fits)
    rec.items = rows(schema.items)
    rec.covariances = rows(schema.item_covariance)
    return rec
