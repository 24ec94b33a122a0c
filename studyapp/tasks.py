"""Celery tasks of the study app.

Tasks stay thin: they call `generation` or `analysis` and store what comes back.
"""

import os
from pathlib import Path

from celery import shared_task
from django.conf import settings

from generation.gallery import GalleryOptions, render_clip
from studyapp.stimuli import clips


@shared_task(bind=True)
def ping(self, value: int) -> dict[str, object]:
    """Prove a worker ran this: its hostname and pid, and `value` doubled.

    Health checks and tests use it to tell a real round trip through the broker,
    a worker and the result backend from a task run in the caller's process.
    """
    return {"hostname": self.request.hostname, "pid": os.getpid(), "doubled": 2 * value}


@shared_task
def render_natural_clip(bvh_path: str, out_dir: str, options: dict) -> dict:
    """Render one natural clip of the gallery (video and contact sheet); its index entry.

    Idempotent: a clip whose files exist is not drawn again.
    """
    return render_clip(Path(bvh_path), Path(out_dir), GalleryOptions.from_dict(options))


# acks_late with reject_on_worker_lost: a worker process killed mid-render (out of
# memory, a deploy) puts the message back, so another attempt finishes the clip.
@shared_task(bind=True, acks_late=True, reject_on_worker_lost=True)
def generate_stimulus(self, stimulus_id: int) -> dict:
    """Render one stimulus: queued -> running -> done (or failed with the reason).

    Idempotent: a stimulus already done with its video in place is left alone, and so is
    one that was sent again since this message (the later task renders it).
    """
    stimulus = clips.claim(stimulus_id, self.request.id)
    if stimulus is None:
        return {"stimulus": stimulus_id, "status": "nothing to do"}
    try:
        duration = clips.render_stimulus(stimulus)
    except Exception as error:  # the reason is shown on the progress page, where it can be retried
        clips.finish(stimulus, error=f"{type(error).__name__}: {error}")
        return {"stimulus": stimulus_id, "status": "failed", "attempt": stimulus.attempts}
    clips.finish(stimulus, duration_s=duration)
    return {"stimulus": stimulus_id, "status": "done", "attempt": stimulus.attempts}


@shared_task(bind=True, acks_late=True, reject_on_worker_lost=True)
def sample_stimuli(self, sent: list[tuple[int, str]]) -> dict:
    """Sample every stimulus of one system (on STUDY_SAMPLE_QUEUE), then send each to be
    rendered (on STUDY_RENDER_QUEUE) under the task id the row was given."""
    ready = clips.sample_ahead([(int(pk), task_id) for pk, task_id in sent])
    for stimulus_id, task_id in ready:
        generate_stimulus.apply_async((stimulus_id,), task_id=task_id, queue=settings.STUDY_RENDER_QUEUE)
    return {"sampled": len(ready), "of": len(sent), "hostname": self.request.hostname}
