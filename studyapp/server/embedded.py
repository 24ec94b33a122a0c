"""The server-less defaults: where the demo keeps its database, queue and results.

With no environment set, the app runs from one folder (`var/` under the repository,
or `STUDYAPP_VAR_DIR`): a SQLite database, kombu's filesystem transport as the
Celery broker, Celery's filesystem result backend and a secret key made there once. Production replaces each of
these through `DATABASE_URL`, `CELERY_BROKER_URL` and `CELERY_RESULT_BACKEND`.
"""

import os
import secrets
from pathlib import Path

# kombu ignores the host of a filesystem URL but warns on every clone of a
# connection that has none, which floods the worker log.
FILESYSTEM_BROKER_URL = "filesystem://localhost//"
# kombu's filesystem transport writing each message whole before it is seen (broker_files).
FILESYSTEM_TRANSPORT = "studyapp.server.broker_files:Transport"

# kombu polls the folders; its 1 s default would make a 1 s control ping miss
# replies, and a tenth of a second costs next to nothing in directory listings.
FILESYSTEM_POLLING_INTERVAL_S = 0.1


def is_filesystem_broker(url: str) -> bool:
    return url.startswith("filesystem:")


def filesystem_broker_options(var_dir: Path) -> dict[str, object]:
    """Transport options for kombu's filesystem broker under `var_dir/broker/`.

    Producers write and consumers read the same `queue` folder, so every process
    pointed at `var_dir` shares one broker. The folders are created here because
    kombu assumes they exist.
    """
    broker_dir = var_dir / "broker"
    queue_dir = broker_dir / "queue"
    control_dir = broker_dir / "control"
    for folder in (queue_dir, control_dir):
        folder.mkdir(parents=True, exist_ok=True)
    return {
        "data_folder_in": str(queue_dir),
        "data_folder_out": str(queue_dir),
        "control_folder": str(control_dir),
        "polling_interval": FILESYSTEM_POLLING_INTERVAL_S,
    }


def filesystem_result_backend_url(var_dir: Path) -> str:
    """A `file://` result backend under `var_dir`, created because Celery requires it."""
    results_dir = var_dir / "celery-results"
    results_dir.mkdir(parents=True, exist_ok=True)
    return f"file://{results_dir.resolve()}"


def stored_secret_key(var_dir: Path) -> str:
    """A random secret key kept in `var_dir/secret-key` (owner-only), made on first use.

    The embedded setup runs with DEBUG off like production, so it needs a key that
    nobody else knows and that survives restarts (sessions and logins depend on it).
    """
    path = var_dir / "secret-key"
    if not path.exists():
        draft = var_dir / f".secret-key.{os.getpid()}.part"
        draft.touch(mode=0o600)
        draft.write_text(secrets.token_urlsafe(50))
        try:
            path.hardlink_to(draft)  # atomic and refused if it exists: processes starting at once agree
        except FileExistsError:
            pass
        finally:
            draft.unlink()
    return path.read_text().strip()
