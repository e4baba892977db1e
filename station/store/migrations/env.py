"""Alembic's environment: the connection is handed over by :mod:`station.store.db` (never an
alembic.ini, never a URL of its own), and SQLite tables are altered in batch mode (SQLite lacks
most of ALTER TABLE)."""

from __future__ import annotations

from alembic import context

from station.store.schema import metadata


def run() -> None:
    connection = context.config.attributes["connection"]
    context.configure(
        connection=connection,
        target_metadata=metadata,
        render_as_batch=connection.dialect.name == "sqlite",
        transaction_per_migration=False,
    )
    with context.begin_transaction():
        context.run_migrations()


# Alembic's context exists only while Alembic runs this file (an import of the package, as the
# layering test does, finds none)
if getattr(context, "config", None) is not None:
    run()
