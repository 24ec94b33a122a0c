"""Stimuli whose task died with a whole worker are found and sent again within a minute.

The quick tests drive ``studyapp.stimuli.lost_tasks`` against a private filesystem broker; the
slow one kills a real worker's whole process group mid-render (taking its prefetched
messages with it, as the filesystem broker never redelivers) and has a second worker
send them again and finish every clip, leaving no partial file.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
import uuid
from datetime import timedelta
from pathlib import Path
from types import SimpleNamespace

import pytest
from django.utils import timezone

from studyapp.models import Stimulus, System
from studyapp.server.celery import app as celery_app
from studyapp.stimuli.dispatch import queue_stimuli
from studyapp.stimuli.lost_tasks import (SAMPLING_TASK, beat, held_task_ids, lost_stimuli, resend_lost,
                                 waiting_task_ids)
from tests.study_fixtures import make_study
from tests.study_setup import study_files
from tests.test_celery_roundtrip import clean_env
from tests.test_study_researcher import queue  # noqa: F401 (a fixture: a private filesystem broker)
from tests.test_study_worker import RESEARCHER, wait_for

REPO = Path(__file__).resolve().parents[1]


def stimuli_of(role: str, controls: int = 3) -> list[Stimulus]:
    """The stimuli of one system of a study whose systems have their sources: natural clips
    (each rendered by a task of its own), or a checkpoint (all sampled by one task)."""
    study = make_study(controls=controls)
    for system in study.systems.all():
        if system.role == System.Role.MODEL:
            system.checkpoint, system.kind = f"{system.name}.safetensors", "moglow"
        elif system.role == System.Role.NATURAL:
            system.kind = System.SourceKind.NATURAL
        system.save(update_fields=["checkpoint", "kind"])
    return list(study.stimuli.filter(system__name="MoGlow" if role == System.Role.MODEL else "NAT").order_by("pk"))


def sent(stimuli: list[Stimulus]) -> list[Stimulus]:
    """The rows queued to the broker, as generating does."""
    Stimulus.objects.filter(pk__in=[s.pk for s in stimuli]).update(status=Stimulus.Status.PENDING)
    assert queue_stimuli([Stimulus.objects.get(pk=s.pk) for s in stimuli]) == len(stimuli)
    return [Stimulus.objects.get(pk=s.pk) for s in stimuli]


def age(stimuli: list[Stimulus], seconds: float) -> None:
    Stimulus.objects.filter(pk__in=[s.pk for s in stimuli]).update(updated=timezone.now() - timedelta(seconds=seconds))


@pytest.mark.django_db
def test_the_broker_lists_the_task_ids_waiting_in_the_queue(queue):
    rows = sent(stimuli_of(System.Role.NATURAL))
    with celery_app.connection_for_write() as connection:
        waiting = waiting_task_ids(connection, celery_app.conf.task_default_queue)
    assert waiting == {row.task_id for row in rows}


@pytest.mark.django_db
def test_a_sampling_task_stands_for_the_rows_it_carries_waiting_and_held(queue):
    rows = sent(stimuli_of(System.Role.MODEL))
    [message] = list(queue.iterdir())  # one sampling task for all of the system's rows
    with celery_app.connection_for_write() as connection:
        waiting = waiting_task_ids(connection, celery_app.conf.task_default_queue)
    assert {row.task_id for row in rows} < waiting and len(waiting) == len(rows) + 1
    request = SimpleNamespace(name=SAMPLING_TASK, args=([(row.pk, row.task_id) for row in rows],))
    assert set(held_task_ids({"sampling-task": request})) == {"sampling-task", *(row.task_id for row in rows)}


@pytest.mark.django_db
def test_a_row_whose_message_is_gone_and_that_no_worker_touches_is_sent_again(queue, settings):
    waiting, taken, held = sent(stimuli_of(System.Role.NATURAL))
    # A dead worker had taken `taken` from the queue (and its file with it); a live worker holds `held`.
    for message in queue.iterdir():
        if taken.task_id in message.read_text() or held.task_id in message.read_text():
            message.unlink()
    age([waiting, taken, held], settings.STUDY_LOST_AFTER_S + 5)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("studyapp.stimuli.lost_tasks.worker_state.requests", {held.task_id: object()})
        beat(celery_app)  # this worker's beat: touches `held`, then sends what was lost

    after = {s.pk: s for s in Stimulus.objects.filter(pk__in=[waiting.pk, taken.pk, held.pk])}
    assert after[waiting.pk].task_id == waiting.task_id  # still waiting in the queue: left alone
    assert after[held.pk].task_id == held.task_id and after[held.pk].updated > held.updated  # alive: touched
    assert after[taken.pk].task_id != taken.task_id and after[taken.pk].status == Stimulus.Status.QUEUED
    with celery_app.connection_for_write() as connection:
        assert after[taken.pk].task_id in waiting_task_ids(connection, celery_app.conf.task_default_queue)


@pytest.mark.django_db
def test_a_row_touched_within_the_minute_is_not_judged_lost(queue, settings):
    [row] = sent(stimuli_of(System.Role.NATURAL, controls=1))
    for message in queue.iterdir():
        message.unlink()
    age([row], settings.STUDY_LOST_AFTER_S - 10)
    assert lost_stimuli(set()) == []
    assert resend_lost(celery_app) == 0
    age([row], settings.STUDY_LOST_AFTER_S + 1)
    assert [s.pk for s in lost_stimuli(set())] == [row.pk]


# The workers' re-send time shortened, as a deployment may (the default is 45 s): the
# tests wait for it, and each rule holds at any time (three beats fit in it).
QUICK_HEARTBEAT_S, QUICK_LOST_AFTER_S = 2.0, 9.0
QUICK_RESEND = {"STUDY_HEARTBEAT_S": str(QUICK_HEARTBEAT_S), "STUDY_LOST_AFTER_S": str(QUICK_LOST_AFTER_S)}


@pytest.mark.slow
def test_a_whole_worker_killed_loses_no_stimulus(motion_data, tmp_path, tmp_path_factory):
    var = tmp_path / "var"
    files = study_files(motion_data, tmp_path_factory.getbasetemp())
    env = clean_env(STUDYAPP_VAR_DIR=str(var), MOTION_DATA=str(files.clips), DJANGO_SUPERUSER_PASSWORD="pw-for-tests",
                    OMP_NUM_THREADS="1", **QUICK_RESEND)
    controls = tmp_path / "three.json"
    controls.write_text(json.dumps([{"segments": [{"type": "straight", "speed": 100 + 10 * i, "seconds": 6}]}
                                    for i in range(3)]))
    stimuli_folder = var / "media" / "stimuli"
    log_path = tmp_path / "worker.log"

    def start_worker(name: str) -> subprocess.Popen:
        return subprocess.Popen(
            [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool=prefork", "--concurrency=1",
             "--hostname", f"{name}-{uuid.uuid4().hex[:6]}@%h", "--loglevel=info", "--without-mingle",
             "--without-gossip"], cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)

    with log_path.open("wb") as log:
        first = start_worker("first")
        second = None
        researcher = subprocess.Popen([sys.executable, "-c", RESEARCHER, str(files.good), str(controls)], cwd=REPO,
                                      env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            wait_for(lambda: stimuli_folder.is_dir() and list(stimuli_folder.glob(".*.part")), 180,
                     "the first render to start", log_path)
            os.killpg(first.pid, signal.SIGKILL)  # the whole worker, with the messages it prefetched
            first.wait(timeout=10)
            with sqlite3.connect(var / "db.sqlite3") as db:
                stuck = db.execute("SELECT COUNT(*) FROM studyapp_stimulus WHERE status IN ('queued', 'running')").fetchone()
            waiting = len(list((var / "broker" / "queue").glob("*.msg")))
            assert stuck[0] == 3 and waiting < 3  # the dead worker took at least the clip it was rendering
            killed_at = time.monotonic()
            second = start_worker("second")
            out, err = researcher.communicate(timeout=240)
            recovered_in = time.monotonic() - killed_at
        finally:
            researcher.kill()
            for worker in (first, second):
                if worker is not None and worker.poll() is None:
                    os.killpg(worker.pid, signal.SIGKILL)
                    worker.wait(timeout=10)
    worker_log = log_path.read_text(errors="replace")
    assert researcher.returncode == 0, f"{out}\n{err[-2000:]}\nworker log:\n{worker_log[-3000:]}"
    assert "sending again" in worker_log and "lost with their worker" in worker_log

    with sqlite3.connect(var / "db.sqlite3") as db:
        rows = db.execute("SELECT token, status FROM studyapp_stimulus").fetchall()
    assert [status for _, status in rows] == ["done"] * 3
    assert sorted(p.name for p in stimuli_folder.iterdir()) == sorted(f"{token}.mp4" for token, _ in rows)  # no .part
    # Sent again within a minute of being judged lost, and three clips rendered besides.
    assert recovered_in < QUICK_LOST_AFTER_S + 60 + 90, recovered_in
