"""compose's Redis keeps the queue on disk: a Celery message sent to a redis-server started with
compose's own command is there again after the server is killed (SIGKILL, no shutdown save)
and restarted on the same folder, as its volume would be."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
import redis
from celery import Celery

from tests.test_compose import load_compose
from tests.throwaway_postgres import free_port

QUEUE = "persistence-check"


def start_redis(folder: Path, port: int) -> subprocess.Popen:
    """redis-server with compose's arguments, its data in ``folder`` (the container's /data)."""
    command = load_compose()["services"]["redis"]["command"]
    assert command[0] == "redis-server"
    server = subprocess.Popen([*command, "--port", str(port), "--bind", "127.0.0.1", "--dir", str(folder),
                               "--save", ""], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    client = redis.Redis(port=port)
    for _ in range(100):
        try:
            client.ping()
            return server
        except redis.ConnectionError:
            time.sleep(0.05)
    server.kill()
    pytest.fail("redis-server did not answer")


def test_a_queued_task_outlives_a_killed_redis(tmp_path):
    port = free_port()
    server = start_redis(tmp_path, port)
    try:
        app = Celery("persistence", broker=f"redis://127.0.0.1:{port}/0")
        app.send_task("studyapp.tasks.render_stimulus", args=[1, "task-id"], queue=QUEUE)
        assert redis.Redis(port=port).llen(QUEUE) == 1
        time.sleep(1.5)  # appendfsync everysec: on disk within a second
        os.kill(server.pid, signal.SIGKILL)  # no shutdown, so nothing is saved on the way out
        server.wait()
        server = start_redis(tmp_path, port)

        kept = redis.Redis(port=port).lrange(QUEUE, 0, -1)
        assert len(kept) == 1 and b"studyapp.tasks.render_stimulus" in kept[0]
    finally:
        server.kill()
        server.wait()
