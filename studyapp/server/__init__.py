"""How the study app runs: settings read from the environment, the embedded defaults
(SQLite, a filesystem broker), the Celery app, the WSGI entry point, health checks, the
files it serves itself, the upload limit, the embedded database backend and the demo."""
