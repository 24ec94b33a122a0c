"""How the study app is deployed and runs: settings read from the environment with embedded
defaults, the Celery app, the WSGI entry point, health checks and the files it serves itself;
the database seams in ``db/``, what comes from outside in ``uploads/``."""
