"""Celery tasks of the study app.

Tasks stay thin: they call `generation` or `analysis` and store what comes back.
"""

import os
from pathlib import Path

from celery import shared_task

from generation.gallery import GalleryOptions, render_clip


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
