"""Stimuli whose task was lost with its worker, found and sent again within a minute.

A worker *process* killed mid-render is covered by ``acks_late`` with
``reject_on_worker_lost``: its message goes back on the queue. A whole *worker* killed
(the machine lost, SIGKILL to its process group) takes every message it had prefetched
with it: kombu's filesystem broker has no redelivery at all, and Redis returns them only
after its visibility timeout (an hour). Their rows would sit queued or running.

So every worker beats a heart: each ``STUDY_HEARTBEAT_S`` (a setting, 10 s) it touches
(``updated``) the rows of the tasks it holds, prefetched or running. A queued or running
row untouched for ``STUDY_LOST_AFTER_S`` (45 s) whose message is not waiting in the
broker's queue has lost its task; the same beat finds such rows and sends them again. Sending gives a row a new task id,
so the old message, should it ever come back, is ignored (``clips.claim``). Where the
broker's queue cannot be listed, nothing is judged lost and the half-hour rule of
``dispatch.queue_stimuli`` remains.
"""

from __future__ import annotations

import base64
import json
import logging
import threading
from datetime import timedelta
from pathlib import Path

from celery.signals import worker_ready, worker_shutdown
from celery.worker import state as worker_state
from django.conf import settings
from django.db import close_old_connections
from django.utils import timezone
from kombu import Connection

from studyapp.models import Stimulus
from studyapp.stimuli.dispatch import queue_stimuli
from studyapp.tasks import sample_stimuli

IN_FLIGHT = (Stimulus.Status.QUEUED, Stimulus.Status.RUNNING)

log = logging.getLogger(__name__)


# A sampling task carries the task ids its rows will be rendered under (dispatch._messages):
# while it waits or runs, so do they.
SAMPLING_TASK = sample_stimuli.name


def carried_task_ids(task_id: str, task_name: str, args) -> list[str]:
    """The task ids a message stands for: its own, and for a sampling task its rows'."""
    if task_name == SAMPLING_TASK and args:
        return [task_id, *(row_task_id for _, row_task_id in args[0])]
    return [task_id]


def held_task_ids(requests: dict) -> list[str]:
    """The task ids a worker holds (``worker_state.requests``), with those they carry."""
    return [carried for task_id, request in list(requests.items())  # one copy while the worker adds to it
            for carried in carried_task_ids(task_id, getattr(request, "name", ""), getattr(request, "args", ()))]


def touch_held(task_ids: list[str]) -> int:
    """Mark the rows of the tasks a live worker holds as alive; how many."""
    if not task_ids:
        return 0
    return Stimulus.objects.filter(task_id__in=task_ids, status__in=IN_FLIGHT).update(updated=timezone.now())


def waiting_task_ids(connection: Connection, queue: str) -> set[str] | None:
    """The task ids of the messages waiting in ``queue``; None where the broker cannot list them."""
    channel = connection.default_channel
    if connection.transport.driver_type == "filesystem":
        payloads = []
        for path in Path(channel.data_folder_in).glob(f"*.{queue}.msg"):
            try:
                payloads.append(path.read_bytes())
            except FileNotFoundError:  # taken by a worker as we looked: no longer waiting
                continue
    elif connection.transport.driver_type == "redis":
        payloads = [payload for priority in channel.priority_steps
                    for payload in channel.client.lrange(channel._q_for_pri(queue, priority), 0, -1)]
    else:
        return None
    waiting = set()
    for payload in payloads:
        try:
            message = json.loads(payload)
            headers = message["headers"]
            body = message["body"]
            if message.get("properties", {}).get("body_encoding") == "base64":
                body = base64.b64decode(body)
            args = json.loads(body)[0] if headers.get("task") == SAMPLING_TASK else ()
            waiting.update(carried_task_ids(headers["id"], headers.get("task", ""), args))
        except (ValueError, KeyError, TypeError, IndexError):
            continue  # not a task message
    return waiting


def lost_stimuli(waiting: set[str]) -> list[Stimulus]:
    """Queued or running rows untouched for STUDY_LOST_AFTER_S whose message is not in ``waiting``."""
    cutoff = timezone.now() - timedelta(seconds=settings.STUDY_LOST_AFTER_S)
    stale = Stimulus.objects.filter(status__in=IN_FLIGHT, updated__lt=cutoff)
    return [stimulus for stimulus in stale if stimulus.task_id not in waiting]


def worker_seen_lately() -> bool:
    """Whether a worker may be at work: a row touched within ``STUDY_LOST_AFTER_S``, the
    time in which a worker's heartbeat touches every row it holds. A row a worker started,
    finished or holds counts, and so does one just queued, which no worker had the time to
    take: the page says "no worker answers" only once rows have waited that long untouched
    and no worker has taken a task since."""
    cutoff = timezone.now() - timedelta(seconds=settings.STUDY_LOST_AFTER_S)
    return Stimulus.objects.filter(updated__gte=cutoff).exclude(status=Stimulus.Status.PENDING).exists()


def release(stimuli: list[Stimulus]) -> list[Stimulus]:
    """Make lost rows pending again (each only if nobody touched it since it was read), so
    that ``queue_stimuli`` sends them; the rows released."""
    released = []
    for stimulus in stimuli:
        if Stimulus.objects.filter(pk=stimulus.pk, status=stimulus.status, task_id=stimulus.task_id,
                                   updated=stimulus.updated).update(status=Stimulus.Status.PENDING):
            stimulus.status = Stimulus.Status.PENDING
            released.append(stimulus)
    return released


def resend_lost(app) -> int:
    """Find the rows whose task was lost and send them again; how many were sent."""
    waiting: set[str] = set()
    with app.connection_for_write() as connection:
        for queue in {settings.STUDY_SAMPLE_QUEUE, settings.STUDY_RENDER_QUEUE}:
            listed = waiting_task_ids(connection, queue)
            if listed is None:
                return 0
            waiting |= listed
    lost = release(lost_stimuli(waiting))
    if lost:
        log.warning("sending again %d stimulus task(s) lost with their worker: %s", len(lost),
                    ", ".join(str(s.pk) for s in lost))
    return queue_stimuli(lost) if lost else 0


def beat(app) -> int:
    """One heartbeat of a worker: touch what it holds, then send again what others lost (how many)."""
    touch_held(held_task_ids(worker_state.requests))
    return resend_lost(app)


class Heartbeat(threading.Thread):
    """The worker's heartbeat thread, from ``worker_ready`` to ``worker_shutdown``."""

    def __init__(self, app) -> None:
        super().__init__(name="stimulus-heartbeat", daemon=True)
        self.app, self.stopped = app, threading.Event()

    def run(self) -> None:
        while not self.stopped.wait(settings.STUDY_HEARTBEAT_S):
            close_old_connections()  # this thread's own database connection, as a request's
            try:
                beat(self.app)
            except Exception:  # a beat must never stop the worker; the next one tries again
                log.exception("the lost-task heartbeat failed")
            finally:
                close_old_connections()


_heartbeat: Heartbeat | None = None


def start_heartbeat(sender, **kwargs) -> None:
    """``worker_ready`` receiver (``sender`` is the worker's consumer)."""
    global _heartbeat
    _heartbeat = Heartbeat(sender.app)
    _heartbeat.start()


def stop_heartbeat(sender=None, **kwargs) -> None:
    """``worker_shutdown`` receiver."""
    if _heartbeat is not None:
        _heartbeat.stopped.set()


# Each worker imports this module (``imports`` in studyapp.server.celery): it touches the rows of
# the tasks it holds and sends again those a dead worker took with it.
worker_ready.connect(start_heartbeat, weak=False)
worker_shutdown.connect(stop_heartbeat, weak=False)
