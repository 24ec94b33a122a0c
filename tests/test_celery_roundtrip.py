"""A real Celery worker process runs the ping task, over Redis and over the embedded broker.

Each test starts `celery -A studyapp worker --pool=solo` from the repository root
with only environment variables changed, sends `studyapp.tasks.ping` from a second
process (so both sides read the settings as a deployment would), checks the result
came from the worker, and checks the worker answers the health page's control ping.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
import redis

REPO_ROOT = Path(__file__).resolve().parent.parent
REDIS_URL = os.environ.get("REDIS_URL", "redis://127.0.0.1:6379/0")

# Runs in a fresh interpreter: send ping to the worker's queue, wait for the
# result, then probe health until the worker answers a control ping.
CLIENT = """
import json, sys, time
import django
django.setup()
from studyapp.server.celery import app
from studyapp.server.health import collect_health
from studyapp.tasks import ping

queue, node = sys.argv[1], sys.argv[2]
result = ping.apply_async(args=(21,), queue=queue).get(timeout=30)
deadline = time.monotonic() + 15
while True:
    report = collect_health(app, 1.0).as_dict()
    if node in report["workers"]["names"] or time.monotonic() > deadline:
        break
print(json.dumps({"result": result, "health": report}))
"""


def clean_env(**overrides: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in {"DATABASE_URL", "CELERY_BROKER_URL", "CELERY_RESULT_BACKEND"}}
    env["DJANGO_SETTINGS_MODULE"] = "studyapp.server.settings"
    env.update(overrides)
    return env


class Worker:
    """A worker subprocess on its own queue, stopped and reaped whatever happens."""

    def __init__(self, env: dict[str, str], log_path: Path) -> None:
        self.queue = f"roundtrip-{uuid.uuid4().hex[:8]}"
        self.node = f"{self.queue}@{socket.gethostname()}"
        self.env = env
        self.log_path = log_path
        command = [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool=solo", "--concurrency=1",
                   "--queues", self.queue, "--hostname", self.node, "--loglevel=info", "--without-mingle", "--without-gossip"]
        self.log = log_path.open("wb")
        # Its own session, so the whole group can be killed if it will not stop.
        self.process = subprocess.Popen(command, cwd=REPO_ROOT, env=env, stdout=self.log, stderr=subprocess.STDOUT, start_new_session=True)

    def log_tail(self) -> str:
        return self.log_path.read_text(errors="replace")[-3000:]

    def stop(self) -> None:
        try:
            if self.process.poll() is None:
                self.process.send_signal(signal.SIGTERM)  # warm shutdown
                try:
                    self.process.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    os.killpg(self.process.pid, signal.SIGKILL)
                    self.process.wait(timeout=5)
        finally:
            self.log.close()


@pytest.fixture
def start_worker(tmp_path: Path) -> Iterator:
    workers: list[Worker] = []

    def start(env: dict[str, str]) -> Worker:
        worker = Worker(env, tmp_path / f"worker-{len(workers)}.log")
        workers.append(worker)
        return worker

    try:
        yield start
    finally:
        for worker in workers:
            worker.stop()


def round_trip(worker: Worker) -> dict:
    try:
        client = subprocess.run([sys.executable, "-c", CLIENT, worker.queue, worker.node], cwd=REPO_ROOT, env=worker.env,
                                capture_output=True, text=True, timeout=50)
    except subprocess.TimeoutExpired:
        pytest.fail(f"client timed out; worker log:\n{worker.log_tail()}")
    assert client.returncode == 0, f"client failed:\n{client.stderr[-3000:]}\nworker log:\n{worker.log_tail()}"
    return json.loads(client.stdout.strip().splitlines()[-1])


def assert_worker_did_it(worker: Worker, outcome: dict) -> None:
    assert outcome["result"] == {"hostname": worker.node, "pid": worker.process.pid, "doubled": 42}
    assert worker.node in outcome["health"]["workers"]["names"], worker.log_tail()
    assert outcome["health"]["broker"]["ok"] is True


def test_ping_round_trip_over_the_embedded_filesystem_broker(start_worker, tmp_path: Path) -> None:
    worker = start_worker(clean_env(STUDYAPP_VAR_DIR=str(tmp_path / "var")))

    outcome = round_trip(worker)

    assert_worker_did_it(worker, outcome)
    assert outcome["health"]["broker"]["detail"] == f"filesystem {tmp_path / 'var' / 'broker' / 'queue'}"
    assert (tmp_path / "var" / "broker" / "queue").is_dir()


def require_redis() -> str:
    """REDIS_URL if a server answers; in CI a missing server fails the test rather than skipping it."""
    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=1, socket_timeout=1).ping()
    except redis.RedisError as exc:
        message = f"no Redis at {REDIS_URL} ({exc}); run scripts/ensure-redis.sh first"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return REDIS_URL


@pytest.mark.redis
def test_ping_round_trip_over_redis(start_worker, tmp_path: Path) -> None:
    redis_url = require_redis()
    worker = start_worker(clean_env(STUDYAPP_VAR_DIR=str(tmp_path / "var"), CELERY_BROKER_URL=redis_url, CELERY_RESULT_BACKEND=redis_url))

    outcome = round_trip(worker)

    assert_worker_did_it(worker, outcome)
    assert outcome["health"]["broker"]["detail"].startswith("redis://")
