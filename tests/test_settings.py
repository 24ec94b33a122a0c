"""Settings come from the environment: embedded defaults, production values, and refusals."""

import json
import os
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent

# Prints the settings that deployment variables control, as a fresh process sees them.
SHOW_SETTINGS = """
import json
from django.conf import settings
print(json.dumps({
    "database": settings.DATABASES["default"]["ENGINE"] + " " + str(settings.DATABASES["default"]["NAME"]),
    "broker": settings.CELERY_BROKER_URL,
    "broker_options": getattr(settings, "CELERY_BROKER_TRANSPORT_OPTIONS", None),
    "results": settings.CELERY_RESULT_BACKEND,
    "media": str(settings.MEDIA_ROOT),
    "hosts": settings.ALLOWED_HOSTS,
    "debug": settings.DEBUG,
}))
"""

DEPLOYMENT_VARIABLES = {"DATABASE_URL", "CELERY_BROKER_URL", "CELERY_RESULT_BACKEND", "MEDIA_ROOT", "SECRET_KEY",
                        "DEBUG", "ALLOWED_HOSTS", "STUDYAPP_VAR_DIR"}


def run_settings(**env: str) -> subprocess.CompletedProcess:
    environment = {k: v for k, v in os.environ.items() if k not in DEPLOYMENT_VARIABLES}
    environment.update(DJANGO_SETTINGS_MODULE="studyapp.settings", **env)
    return subprocess.run([sys.executable, "-c", SHOW_SETTINGS], cwd=REPO_ROOT, env=environment,
                          capture_output=True, text=True, timeout=30)


def test_defaults_need_no_server_and_live_under_the_var_dir(tmp_path: Path) -> None:
    shown = json.loads(run_settings(STUDYAPP_VAR_DIR=str(tmp_path)).stdout)

    assert shown["database"] == f"django.db.backends.sqlite3 {tmp_path / 'db.sqlite3'}"
    assert shown["broker"].startswith("filesystem://")
    assert shown["broker_options"]["data_folder_in"] == str(tmp_path / "broker" / "queue")
    assert shown["results"] == f"file://{tmp_path / 'celery-results'}"
    assert shown["media"] == str(tmp_path / "media")
    assert shown["hosts"] == ["localhost", "127.0.0.1", "[::1]"]
    assert shown["debug"] is True
    assert (tmp_path / "broker" / "control").is_dir() and (tmp_path / "celery-results").is_dir()


def test_production_values_replace_every_default(tmp_path: Path) -> None:
    shown = json.loads(run_settings(
        STUDYAPP_VAR_DIR=str(tmp_path), DEBUG="0", SECRET_KEY="s3cret", ALLOWED_HOSTS="study.example.org, localhost",
        DATABASE_URL="postgres://study:pw@postgres:5432/study", CELERY_BROKER_URL="redis://redis:6379/0",
        CELERY_RESULT_BACKEND="redis://redis:6379/1", MEDIA_ROOT="/data/media",
    ).stdout)

    assert shown == {
        "database": "django.db.backends.postgresql study",
        "broker": "redis://redis:6379/0",
        "broker_options": None,
        "results": "redis://redis:6379/1",
        "media": "/data/media",
        "hosts": ["study.example.org", "localhost"],
        "debug": False,
    }
    assert not (tmp_path / "broker").exists()


def test_debug_off_without_a_secret_key_refuses_to_start(tmp_path: Path) -> None:
    completed = run_settings(STUDYAPP_VAR_DIR=str(tmp_path), DEBUG="off")

    assert completed.returncode != 0
    assert "SECRET_KEY must be set when DEBUG is off" in completed.stderr


def test_an_unreadable_debug_value_is_an_error_not_a_guess(tmp_path: Path) -> None:
    completed = run_settings(STUDYAPP_VAR_DIR=str(tmp_path), DEBUG="maybe")

    assert completed.returncode != 0
    assert "DEBUG='maybe' is not a boolean" in completed.stderr


# A view that fails, requested once with DEBUG off, as in production.
FAILING_REQUEST = """
import django
django.setup()
from django.test import Client
from django.urls import path
import studyapp.urls
def failing(request):
    raise RuntimeError("a deliberate failure")
studyapp.urls.urlpatterns.append(path("failing/", failing))
print(Client(raise_request_exception=False).get("/failing/").status_code)
"""


def test_with_debug_off_a_server_error_is_logged_to_stderr(tmp_path: Path) -> None:
    environment = {k: v for k, v in os.environ.items() if k not in DEPLOYMENT_VARIABLES}
    environment.update(DJANGO_SETTINGS_MODULE="studyapp.settings", STUDYAPP_VAR_DIR=str(tmp_path), DEBUG="0",
                       SECRET_KEY="s3cret-for-the-log-test", ALLOWED_HOSTS="testserver")
    completed = subprocess.run([sys.executable, "-c", FAILING_REQUEST], cwd=REPO_ROOT, env=environment,
                               capture_output=True, text=True, timeout=60)
    assert completed.stdout.strip() == "500"
    assert "RuntimeError: a deliberate failure" in completed.stderr  # not only mailed to ADMINS, who are none
