"""Benchmark: rating submissions with 100 simultaneous participants.

100 simulated participants (studyapp.simulated_participants: real HTTP, cookies, CSRF)
take a 20-clip study at once, against the production shape (gunicorn with threaded
workers, PostgreSQL on 127.0.0.1) and, as the reference measured in the same run,
against the embedded default of ``make demo`` (Django's runserver and SQLite), under
two loads: *saturation* (every participant answers the moment a page arrives: the
most ratings per second the setup takes) and *watching* (each spends WATCH_S on a
clip's page first, as a person watching a clip does). Reported: rating submissions per
second over the whole run (every page of every participant is fetched too), the median
and 95th-percentile latency of a rating submission (the POST and the redirect to the
next clip's page, as a participant waits for it), and a check that the database holds
exactly the ratings the server accepted (answered with its redirect; a rating whose
next page then fails is still counted). The latency target applies to the watching
load: at saturation latency is queueing by construction.

The simulated participants run in this process, on the same 2 cores as the server, so
the figures are a lower bound for a server with a machine of its own.

    python benchmarks/bench_study.py [--participants 100] [--json]

Needs PostgreSQL's server programs (Debian: postgresql); a throwaway cluster is
created in a temporary folder and removed afterwards.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from benchmarks.machine import describe_machine  # noqa: E402
from studyapp.simulated_participants import percentile, run_participants  # noqa: E402

TARGET_P95_S = 1.0  # a watching participant should never wait a second for the next clip
WATCH_S = 4.0  # a short stimulus clip


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def postgres_bin() -> Path:
    """The folder of initdb and pg_ctl: on PATH, or Debian's versioned folder."""
    found = shutil.which("pg_ctl")
    if found and shutil.which("initdb"):
        return Path(found).resolve().parent
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"))
    if not versions:
        subprocess.check_call([str(REPO / "scripts" / "apt-install.sh"), "postgresql"])
        versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"))
    return versions[-1].parent


@contextlib.contextmanager
def throwaway_postgres() -> Iterator[str]:
    """A PostgreSQL cluster on 127.0.0.1 for the length of the block; yields its database URL.

    PostgreSQL refuses to run as root, so as root the cluster belongs to the postgres user.
    """
    binaries, port = postgres_bin(), free_port()
    folder = Path(tempfile.mkdtemp(prefix="bench-pg-"))
    as_owner: list[str] = []
    if os.geteuid() == 0:
        shutil.chown(folder, "postgres")
        as_owner = ["runuser", "-u", "postgres", "--"]
    data = folder / "data"
    run = lambda *args: subprocess.run([*as_owner, *args], check=True, capture_output=True)  # noqa: E731
    run(str(binaries / "initdb"), "-D", str(data), "-U", "postgres", "--auth=trust", "--no-sync")
    run(str(binaries / "pg_ctl"), "-D", str(data), "-l", str(folder / "log"), "-w", "start", "-o",
        f"-p {port} -k {folder} -c listen_addresses=127.0.0.1 -c max_connections=200 -c fsync=on")
    try:
        run(str(binaries / "createdb"), "-h", "127.0.0.1", "-p", str(port), "-U", "postgres", "study")
        yield f"postgres://postgres@127.0.0.1:{port}/study"
    finally:
        run(str(binaries / "pg_ctl"), "-D", str(data), "-m", "fast", "-w", "stop")
        shutil.rmtree(folder, ignore_errors=True)


def django_step(env: dict, step: str) -> str:
    """Run ``setup`` or ``count`` of this script in a process of its own (one database per process)."""
    return subprocess.run([sys.executable, __file__, f"--{step}"], env=env, cwd=REPO, check=True,
                          capture_output=True, text=True).stdout.strip()


def setup_study() -> str:
    """Migrate, and create an open 20-clip study whose stimuli exist (no videos are fetched)."""
    import django

    django.setup()
    from django.core.management import call_command

    from tests.study_fixtures import make_study

    call_command("migrate", verbosity=0)
    study = make_study(owner_name="bench", controls=30, clips_per_participant=20, ratings_per_stimulus=40,
                       training_clips=2, clip_seconds=0.01)
    return study.key


def count_ratings() -> str:
    import django

    django.setup()
    from studyapp.models import Rating

    ratings = Rating.objects.all()
    distinct = ratings.values("assignment_id").distinct().count()
    return json.dumps({"ratings": ratings.count(), "distinct_assignments": distinct})


@contextlib.contextmanager
def serving(command: list[str], env: dict, port: int, log: Path) -> Iterator[str]:
    """The server running for the length of the block, its output in ``log`` (a file: a
    pipe nobody reads would fill and stall the server's request threads)."""
    with log.open("wb") as output:
        process = subprocess.Popen(command, env=env, cwd=REPO, stdout=output, stderr=subprocess.STDOUT,
                                   start_new_session=True)
        url = f"http://127.0.0.1:{port}"
        try:
            for _ in range(300):
                with contextlib.suppress(OSError):
                    urllib.request.urlopen(f"{url}/health.json", timeout=2)
                    break
                if process.poll() is not None:
                    raise RuntimeError(f"the server exited: {log.read_text()[-2000:]}")
                time.sleep(0.1)
            yield url
        finally:
            process.terminate()
            process.wait(timeout=30)


def server_errors(log: Path) -> list[str]:
    """Each distinct error a server logged ("Internal Server Error: /path", then the
    exception its traceback ends in), with how often it happened."""
    counts: dict[str, int] = {}
    lines = log.read_text(errors="replace").splitlines()
    for i, line in enumerate(lines):
        if line.startswith("Internal Server Error: "):
            end = next((j for j in range(i + 1, len(lines)) if lines[j].startswith(("[", "Internal Server Error"))),
                       len(lines))
            causes = [text for text in lines[i + 1:end] if re.match(r"^[\w.]+(Error|Exception): ", text)]
            key = f"{line.split(': ', 1)[1].split('/')[-2] or '/'}: {causes[-1] if causes else 'no traceback'}"
            counts[key] = counts.get(key, 0) + 1
    return [f"{count} x {key}" for key, count in counts.items()]


def measure(name: str, database_url: str, server: str, participants: int, watch_s: float) -> dict:
    env = {**os.environ, "DATABASE_URL": database_url, "DJANGO_SETTINGS_MODULE": "studyapp.settings",
           "DEBUG": "false", "SECRET_KEY": "benchmark-only-secret-key-" + "x" * 40, "ALLOWED_HOSTS": "127.0.0.1"}
    key = django_step(env, "setup")
    port = free_port()
    if server == "gunicorn":
        command = [sys.executable, "-m", "gunicorn", "studyapp.wsgi", "--bind", f"127.0.0.1:{port}",
                   "--workers", "3", "--worker-class", "gthread", "--threads", "8"]
    else:
        command = [sys.executable, "manage.py", "runserver", "--noreload", f"127.0.0.1:{port}"]
    with tempfile.TemporaryDirectory(prefix="bench-server-") as folder:
        log = Path(folder) / "server.log"
        with serving(command, env, port, log) as url:
            start = time.perf_counter()
            outcomes = run_participants(f"{url}/p/{key}/", participants, watch_s=watch_s)
            seconds = time.perf_counter() - start
        errors_logged = server_errors(log)
    latencies = [s for o in outcomes for s in o.rating_latencies_s]
    stored = json.loads(django_step(env, "count"))
    submitted = sum(o.ratings for o in outcomes)
    return {
        "setup": name, "load": f"watching {watch_s:g} s" if watch_s else "saturation",
        "participants": participants, "finished": sum(o.finished for o in outcomes),
        "errors": [o.error for o in outcomes if o.error][:3], "server_errors": errors_logged,
        "ratings_submitted": submitted,
        "ratings_stored": stored["ratings"], "exactly_stored": stored["ratings"] == stored["distinct_assignments"] == submitted,
        "seconds": seconds, "ratings_per_s": submitted / seconds,
        "median_ms": 1000 * percentile(latencies, 0.5), "p95_ms": 1000 * percentile(latencies, 0.95),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--participants", type=int, default=100)
    parser.add_argument("--watch", type=float, default=WATCH_S,
                        help="seconds each participant spends on a clip's page in the watching run (default %(default)s)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--setup", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--count", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.setup or args.count:
        print(setup_study() if args.setup else count_ratings())
        return 0

    rows = []
    for watch_s in (0.0, args.watch):
        with tempfile.TemporaryDirectory(prefix="bench-sqlite-") as folder:
            rows.append(measure("runserver + SQLite (reference)", f"sqlite:///{folder}/db.sqlite3", "runserver",
                                args.participants, watch_s))
        with throwaway_postgres() as url:
            rows.append(measure("gunicorn + PostgreSQL", url, "gunicorn", args.participants, watch_s))
    saturated_reference, saturated, _, watching = rows  # the order of the loop above
    result = {"machine": describe_machine(), "rows": rows,
              "throughput_ratio": saturated["ratings_per_s"] / saturated_reference["ratings_per_s"]}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"machine: {result['machine']['cpu']}, {result['machine']['cores']} cores")
        for row in rows:
            print(f"{row['setup']:<32} {row['load']:<14} {row['finished']}/{row['participants']} finished, "
                  f"{row['ratings_submitted']} ratings in {row['seconds']:.1f} s = {row['ratings_per_s']:.0f}/s, "
                  f"median {row['median_ms']:.0f} ms, p95 {row['p95_ms']:.0f} ms, "
                  f"database holds exactly the accepted ratings: {row['exactly_stored']}")
            for error in row["errors"]:
                print(f"   error: {error}")
            for error in row["server_errors"]:
                print(f"   server: {error}")
        print(f"gunicorn + PostgreSQL: {result['throughput_ratio']:.2f}x the reference's rating throughput at "
              f"saturation; p95 {watching['p95_ms']:.0f} ms while watching (target {TARGET_P95_S * 1000:.0f} ms)")
    # Every setup must store exactly what was accepted; the production one must also serve
    # every request. The reference's errors (SQLite's lock timeouts at saturation) are reported.
    ok = (all(r["exactly_stored"] for r in rows) and not (saturated["errors"] or watching["errors"])
          and watching["p95_ms"] / 1000 < TARGET_P95_S)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
