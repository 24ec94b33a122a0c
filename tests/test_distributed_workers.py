"""The production shape in small: a web process, a sampling worker and rendering workers,
each a process of its own on its own queue, sharing PostgreSQL, Redis and the media and
var folders (as compose.yaml's services share volumes, or machines a network share).

The sampling worker takes STUDY_SAMPLE_QUEUE alone, as compose.yaml's gpu-worker does on
a GPU machine (here with STUDY_DEVICE=cpu); the rendering worker takes STUDY_RENDER_QUEUE.
A researcher builds a study with the study commands, logs in to the web process and
generates the stimuli there; the rendering worker is killed (its process group, by PID)
in the middle of its batch of clips, and a new one takes its place, as compose's
``restart: unless-stopped`` starts one. The clips the dead worker held come back within
the lost-task re-send time (``studyapp.stimuli.lost_tasks``), and every stimulus is rendered
exactly once.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.request
import uuid
from collections import Counter
from collections.abc import Iterator
from http.cookiejar import CookieJar
from pathlib import Path
from urllib.parse import urlencode, urlsplit, urlunsplit

import psycopg
import pytest

from tests.postgres_pass import is_postgres
from tests.study_setup import study_files
from tests.test_celery_roundtrip import clean_env, require_redis
from tests.test_lost_tasks import QUICK_HEARTBEAT_S, QUICK_LOST_AFTER_S, QUICK_RESEND
from tests.throwaway_postgres import free_port, throwaway_postgres

REPO = Path(__file__).resolve().parents[1]
PASSWORD = "pw-for-tests"

# The researcher's commands, in one process: the study, its systems and controls; prints its id.
BUILD = """
import io, sys
import django
django.setup()
from django.core.management import call_command
checkpoint, controls = sys.argv[1:]
call_command("migrate", interactive=False, verbosity=0)
call_command("createsuperuser", interactive=False, username="researcher", email="r@example.org", verbosity=0)
out = io.StringIO()
call_command("create_study", "researcher", "Three queues", "--size", "640", "480", stdout=out)
study = out.getvalue().strip()
call_command("add_system", study, "MoGlow", checkpoint, stdout=io.StringIO())
call_command("add_system", study, "NAT", "--role", "natural", stdout=io.StringIO())
call_command("add_controls", study, "--held-out", "4", "--count", "2", "--file", controls, stdout=io.StringIO())
print(study)
"""
DONE = re.compile(r"Task studyapp\.tasks\.generate_stimulus\[[^]]+\] succeeded in [\d.]+s: "
                  r"\{'stimulus': (\d+), 'status': 'done'")


@contextlib.contextmanager
def postgres_database() -> Iterator[str]:
    """A new, empty database for the length of the block, on the server DATABASE_URL names
    or on a throwaway cluster; yields its URL."""
    named = os.environ.get("DATABASE_URL", "")
    server = contextlib.nullcontext((named, None)) if is_postgres(named) else throwaway_postgres(durable=False)
    with server as (server_url, _):
        name = f"distributed_{uuid.uuid4().hex[:8]}"
        with psycopg.connect(server_url, autocommit=True) as admin:
            admin.execute(f'CREATE DATABASE "{name}"')
        try:
            yield urlunsplit(urlsplit(server_url)._replace(path=f"/{name}"))
        finally:
            with psycopg.connect(server_url, autocommit=True) as admin:
                admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


class Processes:
    """The deployment's processes, each in a session of its own with its log in a file;
    whatever happens, each is killed with its group at the end."""

    def __init__(self, env: dict[str, str], logs: Path, run: str) -> None:
        self.env, self.logs, self.run, self.started = env, logs, run, []

    def start(self, name: str, command: list[str], **env: str) -> subprocess.Popen:
        with (self.logs / f"{name}.log").open("wb") as log:
            process = subprocess.Popen(command, cwd=REPO, env={**self.env, **env}, stdout=log,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        self.started.append(process)
        return process

    def worker(self, name: str, queue: str, **env: str) -> subprocess.Popen:
        """A Celery worker as compose.yaml runs them (prefork, one child), on ``queue``; its
        node name is this run's, as other runs may share the Redis server."""
        return self.start(name, [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--loglevel=info",
                                 "--queues", queue, "--concurrency", "1", "--hostname", f"{name}-{self.run}@%h",
                                 "--without-mingle", "--without-gossip"], **env)

    def log(self, name: str) -> str:
        return (self.logs / f"{name}.log").read_text(errors="replace")

    def tails(self) -> str:
        return "\n".join(f"--- {path.stem}:\n{path.read_text(errors='replace')[-2500:]}"
                         for path in sorted(self.logs.glob("*.log")))

    def stop_all(self) -> None:
        for process in self.started:
            if process.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=10)


class Browser:
    """A researcher's browser: cookies, and the CSRF token of each page's form."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(CookieJar()))

    def get(self, path: str) -> bytes:
        with self.opener.open(self.url + path, timeout=30) as response:
            return response.read()

    def submit(self, path: str, data: dict) -> str:
        """Post the form of the page at ``path`` with ``data``; the page it leads to."""
        token = re.search(r'name="csrfmiddlewaretoken" value="([^"]+)"', self.get(path).decode()).group(1)
        body = urlencode({"csrfmiddlewaretoken": token, **data}).encode()
        with self.opener.open(self.url + path, data=body, timeout=60) as response:
            return response.read().decode()


class Killer:
    """Kills a worker's whole process group (the worker with the clips it prefetched) the
    moment ``condition`` holds, watching from a thread of its own."""

    def __init__(self, condition, worker: subprocess.Popen) -> None:
        self.killed = threading.Event()
        self.thread = threading.Thread(target=self._watch, args=(condition, worker), daemon=True)
        self.thread.start()

    def _watch(self, condition, worker: subprocess.Popen) -> None:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            if condition():
                os.killpg(worker.pid, signal.SIGKILL)
                self.killed.set()
                return
            time.sleep(0.01)

    def wait(self, timeout: float) -> bool:
        return self.killed.wait(timeout)


def wait_for(condition, timeout: float, what: str, processes: Processes):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}\n{processes.tails()}")


def answers(url: str) -> bool:
    """Whether the web process serves pages (its login page)."""
    with contextlib.suppress(OSError):
        with urllib.request.urlopen(f"{url}/login/", timeout=5) as response:
            return response.status == 200
    return False


@pytest.mark.redis
@pytest.mark.slow
def test_a_rendering_worker_killed_mid_batch_leaves_every_stimulus_rendered_once(motion_data, tmp_path,
                                                                                 tmp_path_factory):
    redis_url = require_redis()
    files = study_files(motion_data, tmp_path_factory.getbasetemp())
    controls = tmp_path / "paths.json"
    # Clips long and large enough that a render takes a second or more even on a quiet
    # machine, so the worker is caught holding a batch while it renders.
    controls.write_text(json.dumps([{"segments": [{"type": "straight", "speed": 90 + 15 * i, "seconds": 8}]}
                                    for i in range(4)]))
    run = uuid.uuid4().hex[:8]
    sample_queue, render_queue = f"sample-{run}", f"render-{run}"
    var = tmp_path / "var"  # shared by every process: uploaded checkpoints, sampled motion, media
    stimuli_folder = var / "media" / "stimuli"
    logs = tmp_path / "logs"
    logs.mkdir()
    port = free_port()
    url = f"http://127.0.0.1:{port}"

    with postgres_database() as database_url:
        env = clean_env(DATABASE_URL=database_url, CELERY_BROKER_URL=redis_url, CELERY_RESULT_BACKEND=redis_url,
                        CELERY_QUEUE=f"default-{run}", STUDY_SAMPLE_QUEUE=sample_queue,
                        STUDY_RENDER_QUEUE=render_queue, STUDYAPP_VAR_DIR=str(var), MEDIA_ROOT=str(var / "media"),
                        MOTION_DATA=str(files.clips), SECRET_KEY="distributed-test-" + "x" * 40,
                        ALLOWED_HOSTS="127.0.0.1", DJANGO_SUPERUSER_PASSWORD=PASSWORD, STUDY_SAMPLE_BATCH="2",
                        HEALTH_TIMEOUT_S="5", OMP_NUM_THREADS="1", **QUICK_RESEND)
        built = subprocess.run([sys.executable, "-c", BUILD, str(files.good), str(controls)], cwd=REPO, env=env,
                               capture_output=True, text=True, timeout=300)
        assert built.returncode == 0, built.stderr[-3000:]
        study = int(built.stdout.split()[-1])

        processes = Processes(env, logs, run)
        try:
            processes.start("web", [sys.executable, "-m", "gunicorn", "studyapp.server.wsgi", "--bind", f"127.0.0.1:{port}",
                                    "--workers", "1", "--worker-class", "gthread", "--threads", "4"])
            processes.worker("gpu", sample_queue, STUDY_DEVICE="cpu")  # the GPU machine's worker, on the CPU here
            first = processes.worker("render", render_queue)
            wait_for(lambda: answers(url), 120, "the web process", processes)
            for name in ("gpu", "render"):
                wait_for(lambda: " ready." in processes.log(name), 120, f"the {name} worker", processes)

            researcher = Browser(url)
            researcher.submit("/login/", {"username": "researcher", "password": PASSWORD})
            health = researcher.get("/health/").decode()  # the web process sees both workers
            assert f"gpu-{run}@" in health and f"render-{run}@" in health, health

            def rendering_a_batch() -> bool:
                """The first rendering worker renders one clip and holds more."""
                log = processes.log("render")
                held = log.count("generate_stimulus[") - 2 * log.count("] succeeded in")  # received, not done
                return held >= 2 and stimuli_folder.is_dir() and bool(list(stimuli_folder.glob(".*.part")))

            # A clip renders in under a second, so the worker is watched, and killed the
            # moment it holds a batch, from before the clips are sent (the page that sends
            # them may answer after the worker has rendered them all).
            killer = Killer(rendering_a_batch, first)
            page = researcher.submit(f"/studies/{study}/stimuli/", {"seed": "0"})
            assert "sent to the workers" in page, page[-2000:]
            if not killer.wait(240):
                pytest.fail(f"timed out after 240 s waiting for the rendering worker to hold a batch\n"
                            f"{processes.tails()}")
            first.wait(timeout=10)
            killed_at = time.monotonic()
            processes.worker("render-again", render_queue)

            def progress() -> dict:
                return json.loads(researcher.get(f"/studies/{study}/stimuli/progress.json"))

            state = wait_for(lambda: (s := progress())["counts"]["done"] == s["total"] and s, QUICK_LOST_AFTER_S + 180,
                             "every stimulus to be done", processes)
            recovered_in = time.monotonic() - killed_at
            with psycopg.connect(database_url) as db:
                rows = db.execute("SELECT id, token, status, attempts FROM studyapp_stimulus "
                                  "WHERE study_id = %s", [study]).fetchall()
            video = researcher.get(f"/media/stimuli/{rows[0][1]}.mp4")
        finally:
            processes.stop_all()

    assert state["counts"]["failed"] == 0 and len(rows) == state["total"] >= 8
    assert {status for _, _, status, _ in rows} == {"done"}
    # Each clip rendered to the end exactly once, whichever worker did it; the dead
    # worker's clip was attempted once more, the clips it only held were not.
    rendered = Counter(int(i) for name in ("render", "render-again") for i in DONE.findall(processes.log(name)))
    assert rendered == Counter({stimulus_id: 1 for stimulus_id, _, _, _ in rows}), processes.tails()
    assert sum(attempts for _, _, _, attempts in rows) == len(rows) + 1
    assert sorted(p.name for p in stimuli_folder.iterdir()) == sorted(f"{token}.mp4" for _, token, _, _ in rows)
    assert video[4:8] == b"ftyp"  # the web process serves what the workers rendered on the shared folder
    # The lost clips were found and sent again by a heartbeat, within the re-send time.
    assert "lost with their worker" in processes.log("render-again") + processes.log("gpu")
    assert recovered_in < QUICK_LOST_AFTER_S + 2 * QUICK_HEARTBEAT_S + 60, recovered_in
    # Sampling on the sampling worker alone, rendering on the rendering workers alone.
    sampler = processes.log("gpu")
    assert "Task studyapp.tasks.sample_stimuli[" in sampler and "generate_stimulus[" not in sampler
    assert not any("sample_stimuli[" in processes.log(name) for name in ("render", "render-again"))
