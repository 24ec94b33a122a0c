"""Stimuli made by a real Celery worker over Redis, surviving a worker process killed mid-render.

Everything runs as a deployment would: the researcher's management commands and a
``celery worker`` (prefork, one child) as separate processes sharing a SQLite file and a
Redis queue of their own. While the child renders, it is killed with SIGKILL; the task (acks_late,
reject_on_worker_lost) goes back on the queue, a new child finishes it, and no partial
file is left.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from tests.study_setup import study_files
from tests.test_celery_roundtrip import clean_env, require_redis

REPO = Path(__file__).resolve().parents[1]
CLIP_SECONDS = 6.0  # long enough (about a second of rendering at the least) to catch the child at it


# The researcher's side, in one process (each start costs seconds): the same commands
# a researcher runs, ending with generate_stimuli --wait, which fails on a failed clip.
RESEARCHER = """
import io, sys
import django
django.setup()
from django.core.management import call_command
checkpoint, controls = sys.argv[1:]
call_command("migrate", interactive=False, verbosity=0)
call_command("createsuperuser", interactive=False, username="researcher", email="r@example.org", verbosity=0)
out = io.StringIO()
call_command("create_study", "researcher", "Killed mid-render", "--size", "320", "240", stdout=out)
study = out.getvalue().strip()
call_command("add_system", study, "MoGlow", checkpoint, stdout=io.StringIO())
call_command("add_controls", study, "--file", controls, stdout=io.StringIO())
call_command("generate_stimuli", study, "--wait", "--timeout", "120")
"""


def children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def wait_for(condition, timeout: float, what: str, log: Path):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.02)
    pytest.fail(f"timed out waiting for {what}; worker log:\n{log.read_text(errors='replace')[-3000:]}")


@pytest.mark.redis
@pytest.mark.slow
def test_a_worker_killed_mid_render_is_retried_and_leaves_no_partial_file(motion_data, tmp_path, tmp_path_factory):
    redis_url = require_redis()
    var = tmp_path / "var"
    files = study_files(motion_data, tmp_path_factory.getbasetemp())
    clips, checkpoint = files.clips, files.good
    env = clean_env(STUDYAPP_VAR_DIR=str(var), CELERY_BROKER_URL=redis_url, CELERY_RESULT_BACKEND=redis_url,
                    CELERY_QUEUE=f"stimuli-{uuid.uuid4().hex[:8]}", MOTION_DATA=str(clips),
                    DJANGO_SUPERUSER_PASSWORD="pw-for-tests", OMP_NUM_THREADS="1")
    controls = tmp_path / "long.json"
    controls.write_text(json.dumps({"segments": [{"type": "straight", "speed": 120, "seconds": CLIP_SECONDS}]}))
    log_path = tmp_path / "worker.log"
    with log_path.open("wb") as log:
        worker = subprocess.Popen(
            [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool=prefork", "--concurrency=1",
             "--hostname", f"kill-{uuid.uuid4().hex[:6]}@{socket.gethostname()}", "--loglevel=info",
             "--without-mingle", "--without-gossip"],
            cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            researcher = subprocess.Popen([sys.executable, "-c", RESEARCHER, str(checkpoint), str(controls)], cwd=REPO,
                                          env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            stimuli = var / "media" / "stimuli"
            wait_for(lambda: stimuli.is_dir() and list(stimuli.glob(".*.part")), 120, "the render to start", log_path)
            [child] = children(worker.pid)
            os.kill(child, signal.SIGKILL)
            out, err = researcher.communicate(timeout=150)
        finally:
            worker.send_signal(signal.SIGTERM)
            try:
                worker.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(worker.pid, signal.SIGKILL)
                worker.wait(timeout=5)
    worker_log = log_path.read_text(errors="replace")
    assert researcher.returncode == 0, f"{out}\n{err[-2000:]}\nworker log:\n{worker_log[-3000:]}"
    assert "signal 9" in worker_log or "SIGKILL" in worker_log, worker_log[-3000:]

    with sqlite3.connect(var / "db.sqlite3") as db:
        rows = db.execute("SELECT token, status, attempts, duration_s, error FROM studyapp_stimulus").fetchall()
    [(token, status, attempts, duration, error)] = rows
    assert (status, attempts, duration, error) == ("done", 2, CLIP_SECONDS, "")
    assert sorted(p.name for p in stimuli.iterdir()) == [f"{token}.mp4"]
    assert (stimuli / f"{token}.mp4").stat().st_size > 10_000
