"""The study web app: one Django app in subpackages by who uses what (``designs``,
``participants``, ``researchers``, ``stimuli``, ``server``), plus its Celery app.

Importing the Celery app here binds `@shared_task` functions to it as soon as
Django loads, so web processes and workers send tasks through the same app. It is
named ``app`` because that is the first name `celery -A studyapp` looks for.
"""

from studyapp.server.celery import app

__all__ = ["app"]
