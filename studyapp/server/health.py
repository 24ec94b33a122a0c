"""Health probes for the database, the Celery broker and the live workers.

Each probe is real (a query, a broker connection, a broadcast ping) and bounded
by a timeout, so `/health/` answers within a couple of seconds even when the
broker is down. Probes report failures; they never raise them.
"""

import os
from dataclasses import asdict, dataclass

from celery import Celery
from django.db import connections
from kombu import Connection


@dataclass(frozen=True)
class Check:
    ok: bool
    detail: str


@dataclass(frozen=True)
class HealthReport:
    database: Check
    broker: Check
    # Node names answering a control ping; empty when the broker is down,
    # because nothing can answer without one.
    workers: list[str]

    @property
    def ok(self) -> bool:
        return self.database.ok and self.broker.ok and bool(self.workers)

    @property
    def status(self) -> str:
        return "ok" if self.ok else "degraded"

    def as_dict(self) -> dict[str, object]:
        return {
            "status": self.status,
            "database": asdict(self.database),
            "broker": asdict(self.broker),
            "workers": {"count": len(self.workers), "names": self.workers},
        }


def check_database(alias: str = "default") -> Check:
    """Run a query on the database; a connection alone can be stale or lazy."""
    try:
        with connections[alias].cursor() as cursor:
            cursor.execute("SELECT 1")
            cursor.fetchone()
    except Exception as exc:  # any failure is the answer, not an error of the probe
        return Check(False, f"{type(exc).__name__}: {exc}")
    return Check(True, connections[alias].vendor)


def check_broker(connection: Connection, timeout_s: float) -> Check:
    """Connect to the broker once, without the retry loop Celery uses for work."""
    try:
        connection.ensure_connection(max_retries=1, interval_start=0, interval_step=0, timeout=timeout_s)
        if connection.transport.driver_type == "filesystem":
            # Connecting to kombu's filesystem transport touches no folder, so
            # check the one that every message is written to.
            queue_dir = connection.transport_options["data_folder_out"]
            if not os.access(queue_dir, os.W_OK):
                return Check(False, f"queue folder {queue_dir} is not writable")
            return Check(True, f"filesystem {queue_dir}")
    except Exception as exc:  # any failure is the answer, not an error of the probe
        return Check(False, f"{type(exc).__name__}: {exc}")
    return Check(True, connection.as_uri())  # as_uri() masks any password


def live_workers(app: Celery, connection: Connection, timeout_s: float) -> list[str]:
    """Names of the workers that answer a broadcast ping within `timeout_s`.

    kombu's filesystem transport supports fanout exchanges, so this works for
    the embedded broker as well as for Redis (checked by the round-trip test).
    One cost there: a worker killed without a warm shutdown leaves its pidbox
    bound, so each ping leaves one small message file for it until a worker
    with the same name starts again and drains them.
    """
    try:
        replies = app.control.ping(timeout=timeout_s, connection=connection)
    except Exception:  # a broker that failed after the connection check: no worker seen
        return []
    return sorted(name for reply in replies for name in reply)


def collect_health(app: Celery, timeout_s: float) -> HealthReport:
    """Probe everything; bounded by about twice `timeout_s` in the worst case."""
    database = check_database()
    with app.connection_for_write(connect_timeout=timeout_s) as connection:
        broker = check_broker(connection, timeout_s)
        workers = live_workers(app, connection, timeout_s) if broker.ok else []
    return HealthReport(database=database, broker=broker, workers=workers)
