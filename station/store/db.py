"""Opening a season store: an SQLite file (the default, at the track) or a PostgreSQL database
(``postgresql://user@host/db``, a team's server), brought to this station's schema by Alembic.

- A new store (a file that does not exist yet, an empty database) is created, when the command
  writes; a command that only reads says there is no store.
- A store made by an older station is upgraded on open, in one transaction, with one line
  saying so; one made by a newer station (a revision this one does not know) is refused.
- A file that is not a store, a database that holds other tables, a wrong URL or password,
  a server that cannot be reached: one line (:class:`StoreError`), never a traceback.

SQLite runs in WAL mode, so a reader (``season list``, the report) works while a station
writes, and a writer that finds another writing waits (busy timeout) instead of failing; a
writing transaction takes the write lock at its start (``BEGIN IMMEDIATE``), so two writers
never deadlock half-way. On PostgreSQL the migration holds an advisory lock, so two stations
opening a new database at once create it once.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa

from station.errors import InputError
from station.store import configured

#: the store when none is given (beside the sessions ``station record`` makes)
DEFAULT_STORE = os.path.join("sessions", "season.db")
#: how long a writer waits for another (SQLite busy timeout; PostgreSQL lock waits are unbounded)
BUSY_TIMEOUT_S = 30.0
#: how long to wait for a PostgreSQL server to answer a connection
CONNECT_TIMEOUT_S = 10
_MIGRATION_LOCK = 7_020_020  # pg_advisory_xact_lock key: "issue 20"
_MIGRATIONS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "migrations")


class StoreError(InputError):
    """The store cannot be opened or written: one line, exit status 2."""


@dataclass
class Store:
    """An open season store."""

    engine: sa.Engine
    where: str  # the path, or the URL without its password: what messages name

    @property
    def dialect(self) -> str:
        return self.engine.dialect.name

    @contextlib.contextmanager
    def writing(self) -> Iterator[sa.Connection]:
        """One writing transaction: committed at the end, rolled back on any error."""
        with self.engine.connect() as conn:
            conn.execution_options(station_write=True)
            with conn.begin():
                yield conn

    @contextlib.contextmanager
    def reading(self) -> Iterator[sa.Connection]:
        with self.engine.connect() as conn, conn.begin():
            yield conn

    def close(self) -> None:
        self.engine.dispose()


def resolve(arg: str | None, config_store: str | None = None) -> str:
    """The store to use: ``--store``, else ``STATION_STORE``, else the config's ``store:``,
    else :data:`DEFAULT_STORE`."""
    return arg or configured(config_store) or DEFAULT_STORE


def is_url(target: str) -> bool:
    return "://" in target


def safe_url(target: str) -> str:
    """The URL without its password (what is printed), or the path as given."""
    if not is_url(target):
        return target
    try:
        return sa.make_url(target).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - a URL that cannot be parsed is named by its scheme only
        return target.split("://", 1)[0] + "://…"


def _engine_url(target: str) -> sa.URL:
    try:
        url = sa.make_url(target)
    except Exception:  # noqa: BLE001 - SQLAlchemy's ArgumentError and ValueError alike
        raise StoreError(
            "not a database URL (postgresql://user@host/db)", path=safe_url(target)
        ) from None
    backend = url.get_backend_name()
    if backend in ("postgresql", "postgres"):
        return url.set(drivername="postgresql+psycopg")
    if backend == "sqlite":
        return url
    raise StoreError(
        f"a season store is an SQLite file or a postgresql:// URL, not {backend}://",
        path=safe_url(target),
    )


def open_store(
    target: str, *, create: bool = False, say: Callable[[str], None] | None = None
) -> Store:
    """Open (and bring up to date) the store at ``target``, a path or a URL. ``create``: make it
    when there is none (the commands that write). ``say`` gets the one line of an upgrade."""
    where = safe_url(target)
    if is_url(target):
        url = _engine_url(target)
        path = url.database if url.get_backend_name() == "sqlite" else None
    else:
        path = target
        url = sa.URL.create("sqlite+pysqlite", database=os.path.abspath(target))
    if path is not None and path not in ("", ":memory:"):
        _check_file(path, where, create)
    engine = _make_engine(url)
    store = Store(engine, where)
    try:
        _migrate(store, create, say or (lambda _m: None))
    except StoreError:
        engine.dispose()
        raise
    except sa.exc.SQLAlchemyError as exc:
        engine.dispose()
        raise database_error(exc, where) from None
    return store


def _check_file(path: str, where: str, create: bool) -> None:
    if os.path.isdir(path):
        raise StoreError("is a folder, not a season store", path=where)
    if os.path.exists(path):
        import stat

        if not stat.S_ISREG(os.stat(path).st_mode):
            raise StoreError("not a regular file: not a season store", path=where)
        return
    if not create:
        raise StoreError("no season store here (station season add SESSION… makes one)",
                         path=where)  # fmt: skip
    parent = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(parent, exist_ok=True)
    except OSError as exc:
        raise StoreError(f"cannot make its folder: {exc.strerror}", path=where) from None


def _make_engine(url: sa.URL) -> sa.Engine:
    if url.get_backend_name() == "sqlite":
        engine = sa.create_engine(url, connect_args={"timeout": BUSY_TIMEOUT_S})

        @sa.event.listens_for(engine, "connect")
        def _connect(dbapi_conn: Any, _record: Any) -> None:
            dbapi_conn.isolation_level = None  # SQLAlchemy's begin event says BEGIN, not pysqlite
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA foreign_keys=ON")
            cur.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")
            cur.close()

        @sa.event.listens_for(engine, "begin")
        def _begin(conn: sa.Connection) -> None:
            write = conn.get_execution_options().get("station_write", False)
            conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")

        return engine
    return sa.create_engine(
        url, connect_args={"connect_timeout": CONNECT_TIMEOUT_S}, pool_pre_ping=True
    )


def database_error(exc: BaseException, where: str) -> StoreError:
    """A database error as one line: the driver's first line, the URL without its password."""
    orig = getattr(exc, "orig", None) or exc
    text = " ".join(str(orig).split("\n")[0].split()) or type(orig).__name__
    low = text.lower()
    if "file is not a database" in low or "not a database" in low:
        return StoreError("not a season store (not an SQLite database)", path=where)
    if isinstance(exc, sa.exc.OperationalError | sa.exc.InterfaceError):
        return StoreError(f"the database cannot be reached or refused: {text}", path=where)
    return StoreError(f"database error: {text}", path=where)


def _alembic_config(conn: sa.Connection) -> Any:
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", _MIGRATIONS)
    cfg.attributes["connection"] = conn
    return cfg


def head_revision() -> str:
    from alembic.script import ScriptDirectory

    cfg = _alembic_config(None)  # type: ignore[arg-type]
    head = ScriptDirectory.from_config(cfg).get_current_head()
    assert head is not None
    return head


def _migrate(store: Store, create: bool, say: Callable[[str], None]) -> None:
    from alembic import command
    from alembic.migration import MigrationContext
    from alembic.script import ScriptDirectory

    with store.writing() as conn:
        if store.dialect == "postgresql":
            conn.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": _MIGRATION_LOCK})
        tables = set(sa.inspect(conn).get_table_names())
        current = MigrationContext.configure(conn).get_current_revision()
        cfg = _alembic_config(conn)
        script = ScriptDirectory.from_config(cfg)
        head = script.get_current_head()
        if current is None:
            if tables - {"alembic_version"}:
                raise StoreError(
                    "not a season store: it holds other tables (give a store of its own)",
                    path=store.where,
                )
            if not create:
                raise StoreError("no season store here (station season add SESSION… makes one)",
                                 path=store.where)  # fmt: skip
            command.upgrade(cfg, "head")
            return
        if current == head:
            return
        known = {s.revision for s in script.walk_revisions()}
        if current not in known:
            raise StoreError(
                f"made by a newer station (schema revision {current}; this station knows up "
                f"to {head}): upgrade station to use it",
                path=store.where,
            )
        command.upgrade(cfg, "head")
        say(f"{store.where}: season store upgraded from schema revision {current} to {head}")
