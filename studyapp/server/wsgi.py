"""WSGI entry point for gunicorn (`gunicorn studyapp.server.wsgi`)."""

import os

from django.core.wsgi import get_wsgi_application
from django.urls import get_resolver

from studyapp.server.clip_urls import answering_signed_clips
from studyapp.server.gc_tuning import freeze_start_up  # importing studyapp tuned the collector

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.server.settings")

django_application = get_wsgi_application()
# Import every view now, as `manage.py serve` does in its checks before it forks: else
# each worker imports them (the researcher pages' analysis modules among them) inside
# its first request (0.6 s of CPU here), which the crowd arriving first waits for.
get_resolver().url_patterns

application = answering_signed_clips(django_application)
freeze_start_up()
