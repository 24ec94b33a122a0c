"""The Celery app that runs the study's background work (`celery -A studyapp worker`).

It reads the `CELERY_*` Django settings, so the broker and result backend follow
the same environment variables as the web process.
"""

import os

from celery import Celery

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.server.settings")

app = Celery("studyapp")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks()
# Imported by every worker as it starts: the heartbeat that re-sends tasks lost with a worker.
app.conf.imports = ("studyapp.stimuli.lost_tasks",)
