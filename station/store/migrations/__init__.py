"""Alembic's migrations of the season store, run by :func:`station.store.db.open_store` (never
by hand): a store made by an older station is brought up to this one's head revision."""
