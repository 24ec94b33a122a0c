"""A PostgreSQL cluster of one's own for the length of a block: the tests' second database
and the benchmarks' production database.

The cluster lives in a temporary folder, listens on 127.0.0.1 on a free port (another,
where that one is taken before the server binds it), trusts
local connections (it holds nothing worth a password) and is stopped and deleted
afterwards. It needs PostgreSQL's server programs (Debian: the postgresql package), which
are installed with ``scripts/apt-install.sh`` when missing.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# How often the tests' servers are started on newly found free ports: a port found free may be
# taken by another process before the server binds it.
STARTS = 3
PORT_TAKEN = "address already in use"  # what Caddy and SeaweedFS (both Go) log for a port taken


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def postgres_bin() -> Path:
    """The folder of initdb and pg_ctl: on PATH, or Debian's versioned folder (installed if missing)."""
    found = shutil.which("pg_ctl")
    if found and shutil.which("initdb"):
        return Path(found).resolve().parent
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"))
    if not versions:
        subprocess.check_call([str(REPO / "scripts" / "apt-install.sh"), "postgresql"])
        versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"))
    return versions[-1].parent


@contextlib.contextmanager
def throwaway_postgres(durable: bool = True) -> Iterator[tuple[str, Path]]:
    """A cluster with an empty database ``study`` for the length of the block; yields its
    database URL and its postmaster.pid file.

    ``durable=False`` turns off fsync and full-page writes: a crash loses the cluster, which
    tests throw away anyway, and commits stop waiting for the disk (tens of milliseconds each
    on a slow one). Benchmarks keep them on, as production does. PostgreSQL refuses to run
    as root, so as root the cluster belongs to the postgres user.
    """
    binaries = postgres_bin()
    folder = Path(tempfile.mkdtemp(prefix="throwaway-pg-"))
    as_owner: list[str] = []
    if os.geteuid() == 0:
        shutil.chown(folder, "postgres")
        as_owner = ["runuser", "-u", "postgres", "--"]
    data = folder / "data"
    run = lambda *args: subprocess.run([*as_owner, *args], check=True, capture_output=True)  # noqa: E731
    durability = "-c fsync=on" if durable else "-c fsync=off -c full_page_writes=off -c synchronous_commit=off"
    log = folder / "log"
    try:
        run(str(binaries / "initdb"), "-D", str(data), "-U", "postgres", "--auth=trust", "--no-sync")
        for start in range(1, STARTS + 1):
            port = free_port()
            try:
                run(str(binaries / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "start", "-o",
                    f"-p {port} -k {folder} -c listen_addresses=127.0.0.1 -c max_connections=200 {durability}")
                break
            except subprocess.CalledProcessError:
                if start == STARTS or "could not bind" not in log.read_text(errors="replace"):
                    raise
                log.unlink()
    except subprocess.CalledProcessError as error:
        detail = (error.stderr or b"").decode(errors="replace") + (log.read_text(errors="replace") if log.exists() else "")
        shutil.rmtree(folder, ignore_errors=True)
        raise RuntimeError(f"the throwaway PostgreSQL cluster did not start: {detail[-2000:]}") from None
    try:
        run(str(binaries / "createdb"), "-h", "127.0.0.1", "-p", str(port), "-U", "postgres", "study")
        yield f"postgres://postgres@127.0.0.1:{port}/study", data / "postmaster.pid"
    finally:
        run(str(binaries / "pg_ctl"), "-D", str(data), "-m", "fast", "-w", "stop")
        shutil.rmtree(folder, ignore_errors=True)
