"""The season store on both engines (an SQLite file, a real PostgreSQL server): the same tests,
the same numbers; migrations up from an older store, a newer one refused; what is not a store
refused in one line; names and notes with quotes and SQL stored verbatim."""

from __future__ import annotations

import datetime as dt
import sqlite3
from pathlib import Path

import pytest
import sqlalchemy as sa

from station.errors import InputError
from station.store import schema
from station.store.db import StoreError, head_revision, open_store
from station.store.writer import ADDED, UNCHANGED, UPDATED, add_session
from tests.season_helpers import make_day


@pytest.fixture(params=["sqlite", "postgresql"])
def store_url(request, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return str(tmp_path / "store" / "season.db")
    server = request.getfixturevalue("pg")
    return server.url(server.create_db())


@pytest.fixture(scope="module")
def days(tmp_path_factory) -> list[Path]:
    base = tmp_path_factory.mktemp("days")
    return [
        make_day(base, "d1", dt.date(2026, 1, 10), "ABBAABBA", {"A": 0.010, "B": 0.011},
                 conditions={"snow_temperature_c": -8.0}, seed=1),
        make_day(base, "d2", dt.date(2026, 1, 11), "BCCBBCCB", {"B": 0.020, "C": 0.0195},
                 conditions={"snow_temperature_c": -2.0}, seed=2),
    ]  # fmt: skip


def _rows(url: str, table: sa.Table) -> list[tuple]:
    store = open_store(url)
    try:
        with store.reading() as c:
            key = [c for c in table.primary_key.columns]
            return [tuple(r) for r in c.execute(sa.select(table).order_by(*key))]
    finally:
        store.close()


def test_add_is_idempotent_and_one_row_per_session(store_url, days):
    store = open_store(store_url, create=True)
    try:
        assert [add_session(store, str(d)) for d in days] == [ADDED, ADDED]
        assert [add_session(store, str(d)) for d in days] == [UNCHANGED, UNCHANGED]
        with store.reading() as c:
            n = c.execute(sa.select(sa.func.count()).select_from(schema.sessions)).scalar()
            nd = c.execute(sa.select(sa.func.count()).select_from(schema.descents)).scalar()
            items = c.execute(
                sa.select(schema.items.c.item).where(schema.items.c.grouping == "item")
            ).scalars()
            assert sorted(items) == sorted(["pair A / blue", "pair B / blue"] * 1
                                           + ["pair B / blue", "pair C / blue"])  # fmt: skip
        assert (n, nd) == (2, 16)
    finally:
        store.close()


def test_an_annotated_session_updates_its_rows(store_url, tmp_path):
    from station.session import folder as sessions
    from station.session.records import InvalidMark

    day = make_day(tmp_path, "d", dt.date(2026, 1, 12), "ABBAABBA", {"A": 0.01, "B": 0.011})
    store = open_store(store_url, create=True)
    try:
        assert add_session(store, str(day)) == ADDED
        sessions.append_annotation(str(day), InvalidMark(3, "fell"))
        assert add_session(store, str(day)) == UPDATED
        with store.reading() as c:
            d = schema.descents
            reason = c.execute(sa.select(d.c.invalid_reason).where(d.c.number == 3)).scalar_one()
            kinds = c.execute(
                sa.select(schema.annotation_log.c.kind).order_by(schema.annotation_log.c.seq)
            ).scalars()
            assert reason == "fell"
            assert list(kinds)[-1] == "invalid"  # the history, in order
    finally:
        store.close()


def test_quotes_and_sql_are_stored_verbatim(store_url, tmp_path):
    evil = 'Robert\'); DROP TABLE sessions;-- "x" % %s :name'
    day = make_day(tmp_path, "d", dt.date(2026, 1, 13), "ABBA", {"A": 0.01, "B": 0.011},
                   items={"A": {"ski": evil, "notes": evil}, "B": {"ski": "B"}})  # fmt: skip
    store = open_store(store_url, create=True)
    try:
        add_session(store, str(day))
        with store.reading() as c:
            d = schema.descents
            got = c.execute(sa.select(d.c.ski, d.c.notes).where(d.c.number == 1)).one()
            assert tuple(got) == (evil, evil)
            assert c.execute(sa.select(sa.func.count()).select_from(schema.sessions)).scalar()
    finally:
        store.close()


def test_both_engines_give_the_same_numbers(pg, days, tmp_path):
    lite = str(tmp_path / "season.db")
    server = pg.url(pg.create_db())
    for url in (lite, server):
        store = open_store(url, create=True)
        for d in days:
            add_session(store, str(d))
        store.close()
    for table in (schema.descents, schema.items, schema.item_covariance, schema.conditions):
        a, b = _rows(lite, table), _rows(server, table)
        assert a == b and a, table.name


def test_an_older_store_is_upgraded_on_open_with_one_line(store_url, days):
    from alembic import command

    from station.store.db import _alembic_config

    store = open_store(store_url, create=True)  # make it at the first revision
    with store.writing() as c:
        command.downgrade(_alembic_config(c), "r0001")
    store.close()
    said: list[str] = []
    store = open_store(store_url, say=said.append)
    try:
        assert len(said) == 1 and f"upgraded from schema revision r0001 to {head_revision()}" \
            in said[0]  # fmt: skip
        assert add_session(store, str(days[0])) == ADDED
    finally:
        store.close()
    said.clear()
    open_store(store_url, say=said.append).close()
    assert said == []  # once


def test_a_newer_store_is_refused(store_url):
    open_store(store_url, create=True).close()
    eng = sa.create_engine(
        store_url.replace("postgresql://", "postgresql+psycopg://")
        if "://" in store_url
        else f"sqlite:///{store_url}"
    )
    with eng.begin() as c:
        c.execute(sa.text("UPDATE alembic_version SET version_num = 'r9999'"))
    eng.dispose()
    with pytest.raises(StoreError, match="newer station.*r9999"):
        open_store(store_url)


def test_the_schema_of_the_migrations_is_the_schema(store_url):
    store = open_store(store_url, create=True)
    try:
        insp = sa.inspect(store.engine)
        for table in schema.metadata.sorted_tables:
            cols = [c["name"] for c in insp.get_columns(table.name)]
            assert cols == [c.name for c in table.columns], table.name
            pk = insp.get_pk_constraint(table.name)["constrained_columns"]
            assert sorted(pk) == sorted(c.name for c in table.primary_key.columns), table.name
    finally:
        store.close()


def test_what_is_not_a_store_is_one_line(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("not a database\n" * 100)
    with pytest.raises(StoreError, match="not a season store"):
        open_store(str(text))
    other = tmp_path / "other.db"
    with sqlite3.connect(other) as c:
        c.execute("CREATE TABLE t (x)")
    with pytest.raises(StoreError, match="holds other tables"):
        open_store(str(other), create=True)
    with pytest.raises(StoreError, match="no season store"):
        open_store(str(tmp_path / "none.db"))
    assert not (tmp_path / "none.db").exists()
    with pytest.raises(StoreError, match="not mysql"):
        open_store("mysql://u@h/db")


def test_a_wrong_password_or_server_is_one_line_without_the_password(pg):
    url = pg.url(pg.create_db(), password="wrong-pw")
    with pytest.raises(StoreError) as exc:
        open_store(url, create=True)
    assert "wrong-pw" not in str(exc.value) and "***" in str(exc.value)
    assert "\n" not in str(exc.value)
    with pytest.raises(StoreError, match="cannot be reached"):
        open_store("postgresql://u:pw@/db?host=/nonexistent&port=1", create=True)


def test_a_damaged_session_is_refused(tmp_path, store_url):
    store = open_store(store_url, create=True)
    try:
        with pytest.raises(InputError, match="not a session"):
            add_session(store, str(tmp_path))
    finally:
        store.close()
