"""WSGI entry point for gunicorn (`gunicorn studyapp.server.wsgi`)."""

import os

from django.core.wsgi import get_wsgi_application

from studyapp.server.gc_tuning import freeze_start_up  # importing studyapp tuned the collector

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.server.settings")

application = get_wsgi_application()
freeze_start_up()
