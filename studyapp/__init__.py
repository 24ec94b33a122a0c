"""The study web app: one Django app in subpackages by who uses what (``designs``,
``participants``, ``researchers``, ``stimuli``, ``server``), plus its Celery app.

Importing the Celery app here binds `@shared_task` functions to it as soon as
Django loads, so web processes and workers send tasks through the same app. It is
named ``app`` because that is the first name `celery -A studyapp` looks for.

Every process of the project (manage.py, gunicorn, the Celery workers, the tests)
imports this package before torch and Django load, so the garbage collector is tuned
here, once for all of them (``studyapp.server.gc_tuning``).
"""

from studyapp.server.gc_tuning import collect_less_often

collect_less_often()

from studyapp.server.celery import app  # noqa: E402 (after the tuning, which spares its imports)

__all__ = ["app"]
