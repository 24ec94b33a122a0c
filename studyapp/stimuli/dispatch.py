"""Sending a study's stimuli to the Celery workers: queueing, broker errors and re-sending.

``generate_stimuli`` plans the rows (``clips.plan_stimuli``) and queues those not done.
``queue_stimuli`` checks the broker first with a bounded wait, so a stopped broker is a
clear message, not a hung page, and re-sends rows whose task was lost. The domain logic
(what a stimulus is, how it is rendered) stays in ``clips``, which knows nothing of
Celery; this module and ``tasks`` are its only links to the queue.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from datetime import datetime, timedelta

from django.conf import settings
from django.utils import timezone

from studyapp.models import Stimulus, Study
from studyapp.server.celery import app
from studyapp.server.health import check_broker
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.sources import source_of
from studyapp.tasks import generate_stimulus, sample_stimuli

# A queued or running row unchanged this long has lost its task; generating again re-sends
# it. Rendering one clip takes seconds; a long queue is the only reason to wait this long.
STALE_TASK_MINUTES = 30


class BrokerUnavailable(RuntimeError):
    """The task queue's broker did not answer; nothing was queued."""


def _sendable(stimulus: Stimulus, now: datetime) -> bool:
    """Pending or failed; or queued or running with no news for STALE_TASK_MINUTES (its
    message was lost, or its worker died without the broker redelivering it)."""
    if stimulus.status in (Stimulus.Status.PENDING, Stimulus.Status.FAILED):
        return True
    stuck = stimulus.status in (Stimulus.Status.QUEUED, Stimulus.Status.RUNNING)
    return stuck and now - stimulus.updated > timedelta(minutes=STALE_TASK_MINUTES)


@dataclass(frozen=True)
class Marked:
    """A row marked queued under a new task id, and what it was before, for undoing."""

    row: Stimulus
    status: str
    task_id: str
    updated: datetime


def _mark_queued(stimulus: Stimulus) -> Marked | None:
    """Mark the row queued under a new task id; None if somebody changed it since it was
    read (two clicks send it once)."""
    before = Marked(stimulus, stimulus.status, stimulus.task_id, stimulus.updated)
    task_id = str(uuid.uuid4())
    # Marked before sending, since a fast worker may mark it running first.
    marked = Stimulus.objects.filter(pk=stimulus.pk, status=stimulus.status, task_id=stimulus.task_id).update(
        status=Stimulus.Status.QUEUED, task_id=task_id, error="", updated=timezone.now())
    if not marked:
        return None
    stimulus.status, stimulus.task_id = Stimulus.Status.QUEUED, task_id
    return before


def _unmark(marks: list[Marked]) -> None:
    for mark in marks:
        Stimulus.objects.filter(pk=mark.row.pk, task_id=mark.row.task_id).update(
            status=mark.status, task_id=mark.task_id, updated=mark.updated)
        mark.row.status, mark.row.task_id = mark.status, mark.task_id


def _messages(marks: list[Marked]) -> list[tuple[list[Marked], object, tuple, dict]]:
    """(marks, task, args, options) of each message: the rows of a system whose source
    samples go to STUDY_SAMPLE_QUEUE together, the others to STUDY_RENDER_QUEUE one each."""
    sampled: dict[int, list[Marked]] = {}
    messages = []
    for mark in marks:
        row = mark.row
        if source_of(row.system).samples:
            sampled.setdefault(row.system_id, []).append(mark)
        else:
            messages.append(([mark], generate_stimulus, (row.pk,),
                             {"task_id": row.task_id, "queue": settings.STUDY_RENDER_QUEUE}))
    for group in sampled.values():
        messages.append((group, sample_stimuli, ([(m.row.pk, m.row.task_id) for m in group],),
                         {"queue": settings.STUDY_SAMPLE_QUEUE}))
    return messages


def queue_stimuli(stimuli: list[Stimulus], timeout_s: float | None = None) -> int:
    """Send each row that needs it (``_sendable``) to the workers; how many were sent.

    Rows whose source samples a model go, all of one system in one message, to the
    sampling queue, whose task sends each on to the rendering queue; the others go to
    the rendering queue directly. Each send gives the row a new task id and only the
    task with the row's current id may work on it (``clips.claim``), so a row sent
    twice (two clicks, a stuck row re-sent) is rendered once. Raises BrokerUnavailable,
    with the rows not sent left as they were, when the broker does not answer within
    ``timeout_s`` (default: settings.HEALTH_TIMEOUT_S).
    """
    now = timezone.now()
    todo = [s for s in stimuli if _sendable(s, now)]
    if not todo:
        return 0
    timeout_s = settings.HEALTH_TIMEOUT_S if timeout_s is None else timeout_s
    with app.connection_for_write(connect_timeout=timeout_s) as connection:
        broker = check_broker(connection, timeout_s)
        if not broker.ok:
            raise BrokerUnavailable(f"the task queue's broker does not answer ({broker.detail}); "
                                    "nothing was queued: start it (and a worker), then generate again")
        marked = [row for row in map(_mark_queued, todo) if row is not None]
        sent = 0
        messages = _messages(marked)
        for i, (marks, task, args, options) in enumerate(messages):
            try:
                task.apply_async(args, connection=connection, retry=False, **options)
            except Exception as error:  # kombu raises many kinds; all mean "not sent"
                _unmark([mark for later in messages[i:] for mark in later[0]])
                raise BrokerUnavailable(f"sending to the task queue failed after {sent} of {len(todo)} "
                                        f"({type(error).__name__}: {error}); the rest stay as they were") from None
            sent += len(marks)
    return sent


@dataclass(frozen=True)
class Generation:
    total: int
    created: int
    queued: int


def generate_stimuli(study: Study, seed: int = 0, timeout_s: float | None = None) -> Generation:
    """Plan every stimulus of the study and queue the ones not done; BrokerUnavailable if it cannot."""
    stimuli, created = plan_stimuli(study, seed)
    return Generation(len(stimuli), created, queue_stimuli(stimuli, timeout_s))


def retry_stimulus(stimulus: Stimulus, timeout_s: float | None = None) -> int:
    """Queue a failed (or stuck) stimulus again (BrokerUnavailable if the broker is down)."""
    return queue_stimuli([stimulus], timeout_s)
