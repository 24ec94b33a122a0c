"""WSGI entry point for gunicorn (`gunicorn studyapp.server.wsgi`)."""

import os

from studyapp.server.gc_tuning import collect_less_often, freeze_start_up

collect_less_often()

from django.core.wsgi import get_wsgi_application  # noqa: E402 (after the collector's tuning, which spares its imports)

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.server.settings")

application = get_wsgi_application()
freeze_start_up()
