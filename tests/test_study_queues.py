"""Sampling and rendering on two queues, each taken by its own real Celery worker over Redis.

The researcher's commands and two ``celery worker`` processes share a SQLite file and a
Redis database: one worker listens on STUDY_SAMPLE_QUEUE only (a GPU machine's worker, in
production), the other on STUDY_RENDER_QUEUE only. Each task must run on the worker its
queue names, and every clip must come out done.
"""

from __future__ import annotations

import socket
import sqlite3
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from tests.study_setup import study_files
from tests.test_celery_roundtrip import clean_env, require_redis

REPO = Path(__file__).resolve().parents[1]

RESEARCHER = """
import io, sys
import django
django.setup()
from django.core.management import call_command
checkpoint = sys.argv[1]
call_command("migrate", interactive=False, verbosity=0)
call_command("createsuperuser", interactive=False, username="researcher", email="r@example.org", verbosity=0)
out = io.StringIO()
call_command("create_study", "researcher", "Two queues", "--size", "160", "120", stdout=out)
study = out.getvalue().strip()
call_command("add_system", study, "MoGlow", checkpoint, stdout=io.StringIO())
call_command("add_system", study, "NAT", "--role", "natural", stdout=io.StringIO())
call_command("add_controls", study, "--held-out", "1", "--preset", "walk-circle", "stand-still", stdout=io.StringIO())
call_command("generate_stimuli", study, "--wait", "--timeout", "180")
"""


def start_worker(env: dict[str, str], queue: str, log: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool=solo", "-Q", queue,
         "--hostname", f"{queue}@{socket.gethostname()}", "--loglevel=info", "--without-mingle", "--without-gossip"],
        cwd=REPO, env=env, stdout=log.open("wb"), stderr=subprocess.STDOUT, start_new_session=True)


def stop(worker: subprocess.Popen) -> None:
    worker.terminate()
    try:
        worker.wait(timeout=20)
    except subprocess.TimeoutExpired:
        worker.kill()
        worker.wait(timeout=5)


@pytest.mark.redis
@pytest.mark.slow
def test_sampling_and_rendering_tasks_run_on_the_workers_their_queues_name(motion_data, tmp_path, tmp_path_factory):
    redis_url = require_redis()
    files = study_files(motion_data, tmp_path_factory.getbasetemp())
    run = uuid.uuid4().hex[:8]
    sample_queue, render_queue = f"sample-{run}", f"render-{run}"
    var = tmp_path / "var"
    env = clean_env(STUDYAPP_VAR_DIR=str(var), CELERY_BROKER_URL=redis_url, CELERY_RESULT_BACKEND=redis_url,
                    CELERY_QUEUE=f"default-{run}", STUDY_SAMPLE_QUEUE=sample_queue, STUDY_RENDER_QUEUE=render_queue,
                    STUDY_DEVICE="cpu", MOTION_DATA=str(files.clips), DJANGO_SUPERUSER_PASSWORD="pw-for-tests",
                    OMP_NUM_THREADS="1")
    logs = {queue: tmp_path / f"{queue}.log" for queue in (sample_queue, render_queue)}
    workers = [start_worker(env, queue, log) for queue, log in logs.items()]
    try:
        researcher = subprocess.run([sys.executable, "-c", RESEARCHER, str(files.good)], cwd=REPO, env=env,
                                    capture_output=True, text=True, timeout=300)
    finally:
        for worker in workers:
            stop(worker)
    sampler, renderer = (logs[q].read_text(errors="replace") for q in (sample_queue, render_queue))
    assert researcher.returncode == 0, f"{researcher.stderr[-2000:]}\nsampler:\n{sampler[-2000:]}\nrenderer:\n{renderer[-2000:]}"

    with sqlite3.connect(var / "db.sqlite3") as db:
        rows = db.execute("SELECT st.status, sy.name FROM studyapp_stimulus st "
                          "JOIN studyapp_system sy ON sy.id = st.system_id").fetchall()
    model_clips = sum(name == "MoGlow" for _, name in rows)
    assert {status for status, _ in rows} == {"done"} and model_clips >= 3 and len(rows) > model_clips
    # One sampling task for the model system's every control, on the sampling worker only.
    assert sampler.count("Task studyapp.tasks.sample_stimuli[") == 2  # received, succeeded
    assert "succeeded" in sampler and "Task studyapp.tasks.generate_stimulus[" not in sampler
    # Every clip, the model's and NAT's, rendered on the rendering worker only.
    assert renderer.count("Task studyapp.tasks.generate_stimulus[") == 2 * len(rows)
    assert "Task studyapp.tasks.sample_stimuli[" not in renderer
    assert len(list((var / "sampled").glob("*.npz"))) == model_clips


def test_the_queues_default_to_the_one_queue_and_an_unknown_device_is_refused(tmp_path):
    from tests.test_settings import run_settings

    show = ("from django.conf import settings; "
            "print(settings.STUDY_SAMPLE_QUEUE, settings.STUDY_RENDER_QUEUE, settings.STUDY_DEVICE)")
    environment = clean_env(STUDYAPP_VAR_DIR=str(tmp_path), CELERY_QUEUE="only")
    shown = subprocess.run([sys.executable, "-c", show], cwd=REPO, env=environment, capture_output=True, text=True)
    assert shown.stdout.split() == ["only", "only", "auto"]
    refused = run_settings(STUDYAPP_VAR_DIR=str(tmp_path), STUDY_DEVICE="tpu")
    assert refused.returncode != 0 and "STUDY_DEVICE='tpu' is not one of auto, cpu, cuda" in refused.stderr


def test_auto_samples_on_the_cpu_where_no_gpu_is_present():
    import torch

    from studyapp.stimuli.sources import sampling_device

    assert sampling_device("auto") == ("cuda" if torch.cuda.is_available() else "cpu")
    assert sampling_device("cpu") == "cpu"


def test_compose_has_an_optional_gpu_worker_on_the_sampling_queue():
    from tests.test_compose import load_compose

    services = load_compose()["services"]
    gpu, worker = services["gpu-worker"], services["worker"]
    assert gpu["profiles"] == ["gpu"] and "profiles" not in worker
    assert gpu["deploy"]["resources"]["reservations"]["devices"] == [
        {"driver": "nvidia", "count": 1, "capabilities": ["gpu"]}]
    assert gpu["environment"]["STUDY_DEVICE"] == "cuda"
    assert gpu["command"][gpu["command"].index("--queues") + 1] == "${STUDY_SAMPLE_QUEUE:-celery}"
    assert worker["command"][worker["command"].index("--queues") + 1] == "${STUDY_RENDER_QUEUE:-celery}"
    assert gpu["volumes"] == worker["volumes"]
