"""The study web app: Django project and app in one package, plus its Celery app.

Importing the Celery app here binds `@shared_task` functions to it as soon as
Django loads, so web processes and workers send tasks through the same app.
"""

from studyapp.celery import app as celery_app

__all__ = ["celery_app"]
