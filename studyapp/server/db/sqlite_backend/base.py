"""SQLite for a crowd served by one process: its writers take turns instead of polling.

SQLite lets one transaction write at a time. A writer that finds the database locked
sleeps and tries again, up to 100 ms between tries, until its busy timeout; under a crowd
the longest waiters keep losing the race to newcomers that poll more often, so 100
participants entering at once in Django's threaded runserver lost several of them to
"database is locked" after 30 s although the database was never idle. Here each write of
this process (a transaction, which SQLite begins IMMEDIATE, or a lone INSERT, UPDATE or
DELETE) first takes the process's writer lock, which waiting threads are handed as it
frees, without polling. SQLite's busy timeout then arbitrates only between processes (a
Celery worker, a second server).
"""

from __future__ import annotations

import threading

from django.db import OperationalError
from django.db.backends.sqlite3 import base

# A turn waited for this long means something held the database far longer than any
# request should; the write fails as SQLite's own timeout would fail it.
TURN_TIMEOUT_S = 300.0
_WRITES = ("INSERT", "UPDATE", "DELETE", "REPLACE")
_writer = threading.Lock()


def _take_turn() -> None:
    if not _writer.acquire(timeout=TURN_TIMEOUT_S):
        raise OperationalError(f"database is locked: no turn to write within {TURN_TIMEOUT_S:.0f} s")


class TurnTakingCursor(base.SQLiteCursorWrapper):
    """Runs a write made outside a transaction in the process's turn."""

    def execute(self, query, params=None):
        if self.connection.in_transaction or not query.lstrip()[:7].upper().startswith(_WRITES):
            return super().execute(query, params)
        _take_turn()
        try:
            return super().execute(query, params)
        finally:
            _writer.release()

    def executemany(self, query, param_list):
        if self.connection.in_transaction:
            return super().executemany(query, param_list)
        _take_turn()
        try:
            return super().executemany(query, param_list)
        finally:
            _writer.release()


class DatabaseWrapper(base.DatabaseWrapper):
    """Django's SQLite backend whose transactions hold the process's writer lock from BEGIN
    to COMMIT or ROLLBACK (or the connection's close)."""

    _has_turn = False

    def create_cursor(self, name=None):
        return self.connection.cursor(factory=TurnTakingCursor)

    def _start_transaction_under_autocommit(self) -> None:
        _take_turn()
        self._has_turn = True
        try:
            super()._start_transaction_under_autocommit()
        except BaseException:
            self._end_turn()
            raise

    def _set_autocommit(self, autocommit: bool) -> None:
        # Back to autocommit is the end of every transaction begun above (atomic's exit).
        super()._set_autocommit(autocommit)
        if autocommit:
            self._end_turn()

    def _close(self) -> None:
        try:
            super()._close()
        finally:
            self._end_turn()

    def _end_turn(self) -> None:
        if self._has_turn:
            self._has_turn = False
            _writer.release()
