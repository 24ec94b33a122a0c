"""The database's snapshot, per engine: PostgreSQL by ``pg_dump`` (one transaction, so one
consistent state, while the study runs), SQLite by its online backup API (the same, page by
page, without stopping the writers); and the loads into an empty database."""

from __future__ import annotations

import os
import sqlite3
import subprocess
from pathlib import Path

from django.db import connection

SQLITE, POSTGRESQL = "sqlite", "postgresql"
DUMP_NAMES = {SQLITE: "database.sqlite3", POSTGRESQL: "database.pgdump"}


class DatabaseError(Exception):
    """The database could not be dumped or loaded; the message says why."""


def engine() -> str:
    """The engine of the app's database, as backups name it."""
    return POSTGRESQL if connection.vendor == "postgresql" else SQLITE


def _postgres_environment() -> dict[str, str]:
    """libpq's variables for the app's database (its password out of the command line)."""
    given = connection.settings_dict
    variables = {"PGHOST": given.get("HOST"), "PGPORT": str(given.get("PORT") or ""), "PGUSER": given.get("USER"),
                 "PGPASSWORD": given.get("PASSWORD"), "PGDATABASE": given.get("NAME")}
    return {**os.environ, **{name: value for name, value in variables.items() if value}}


def _run(command: list[str], what: str) -> None:
    try:
        done = subprocess.run(command, env=_postgres_environment(), capture_output=True, text=True)
    except FileNotFoundError:
        raise DatabaseError(f"{command[0]} is not installed: it {what} (install PostgreSQL's client programs, "
                            "of the server's major version or newer)") from None
    if done.returncode != 0:
        raise DatabaseError(f"{command[0]} failed: {done.stderr.strip() or f'exit status {done.returncode}'}")


def dump(out: Path) -> None:
    """Write the database's snapshot to ``out``."""
    if engine() == POSTGRESQL:
        # The custom format: compressed, and pg_restore loads it in one transaction.
        _run(["pg_dump", "--format=custom", "--no-owner", "--no-privileges", "--file", str(out)],
             "dumps the database")
        return
    connection.ensure_connection()
    with sqlite3.connect(out) as target:
        connection.connection.backup(target)
    target.close()


def table_count() -> int:
    """How many tables the app's database has (0 for a new, empty one)."""
    with connection.cursor() as cursor:
        return len(connection.introspection.table_names(cursor))


def load(dumped: Path) -> None:
    """Load a snapshot into the app's database, which must be empty; nothing is loaded on an error."""
    if engine() == POSTGRESQL:
        _run(["pg_restore", "--single-transaction", "--exit-on-error", "--no-owner", "--no-privileges",
              "--dbname", connection.settings_dict["NAME"], str(dumped)], "loads the database")
    else:
        connection.ensure_connection()
        with sqlite3.connect(dumped) as source:
            source.backup(connection.connection)
        source.close()
    connection.close()  # the next query opens a connection that sees the loaded tables
