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
    environment.update(DJANGO_SETTINGS_MODULE="studyapp.server.settings", **env)
    return subprocess.run([sys.executable, "-c", SHOW_SETTINGS], cwd=REPO_ROOT, env=environment,
                          capture_output=True, text=True, timeout=30)


def test_defaults_need_no_server_and_live_under_the_var_dir(tmp_path: Path) -> None:
    shown = json.loads(run_settings(STUDYAPP_VAR_DIR=str(tmp_path)).stdout)

    assert shown["database"] == f"studyapp.server.db.sqlite_backend {tmp_path / 'db.sqlite3'}"  # Django's, writers in turn
    assert shown["broker"].startswith("filesystem://")
    assert shown["broker_options"]["data_folder_in"] == str(tmp_path / "broker" / "queue")
    assert shown["results"] == f"file://{tmp_path / 'celery-results'}"
    assert shown["media"] == str(tmp_path / "media")
    assert shown["hosts"] == ["localhost", "127.0.0.1", "[::1]"]
    assert shown["debug"] is False  # a developer turns it on with DEBUG=1
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


SHOW_SECRET_KEY = "from django.conf import settings; print(settings.SECRET_KEY)"


def test_without_a_secret_key_one_is_made_once_under_the_var_dir_and_kept(tmp_path: Path) -> None:
    environment = {k: v for k, v in os.environ.items() if k not in DEPLOYMENT_VARIABLES}
    environment.update(DJANGO_SETTINGS_MODULE="studyapp.server.settings", STUDYAPP_VAR_DIR=str(tmp_path))
    keys = [subprocess.run([sys.executable, "-c", SHOW_SECRET_KEY], cwd=REPO_ROOT, env=environment,
                           capture_output=True, text=True, timeout=30, check=True).stdout.strip() for _ in range(2)]

    assert keys[0] == keys[1] == (tmp_path / "secret-key").read_text()
    assert len(keys[0]) >= 50 and "insecure" not in keys[0]
    assert (tmp_path / "secret-key").stat().st_mode & 0o777 == 0o600
    assert [p.name for p in tmp_path.iterdir() if "secret" in p.name] == ["secret-key"]  # no draft left


def test_an_unreadable_debug_value_is_an_error_not_a_guess(tmp_path: Path) -> None:
    completed = run_settings(STUDYAPP_VAR_DIR=str(tmp_path), DEBUG="maybe")

    assert completed.returncode != 0
    assert "DEBUG='maybe' is not a boolean" in completed.stderr


def test_a_setting_that_cannot_be_used_stops_manage_py_with_one_line_and_status_2(tmp_path: Path) -> None:
    environment = {k: v for k, v in os.environ.items() if k not in DEPLOYMENT_VARIABLES}
    for variable, value, said in (("STUDY_LOST_AFTER_S", "5", "STUDY_LOST_AFTER_S=5 must exceed three heartbeats"),
                                  ("STUDY_HEARTBEAT_S", "0", "STUDY_HEARTBEAT_S=0, which must be positive"),
                                  ("STUDY_SAMPLE_BATCH", "0", "STUDY_SAMPLE_BATCH=0 is not a whole number"),
                                  ("CLIP_URL_LIFETIME_S", "30", "CLIP_URL_LIFETIME_S=30 is under a minute")):
        completed = subprocess.run([sys.executable, "manage.py", "check"], cwd=REPO_ROOT, capture_output=True,
                                   text=True, timeout=60, env={**environment, "STUDYAPP_VAR_DIR": str(tmp_path),
                                                               variable: value})
        assert completed.returncode == 2 and completed.stderr.startswith("manage.py: error: ") and said in completed.stderr
        assert "Traceback" not in completed.stderr and completed.stderr.count("\n") == 1


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
    environment.update(DJANGO_SETTINGS_MODULE="studyapp.server.settings", STUDYAPP_VAR_DIR=str(tmp_path), DEBUG="0",
                       SECRET_KEY="s3cret-for-the-log-test", ALLOWED_HOSTS="testserver")
    completed = subprocess.run([sys.executable, "-c", FAILING_REQUEST], cwd=REPO_ROOT, env=environment,
                               capture_output=True, text=True, timeout=60)
    assert completed.stdout.strip() == "500"
    assert "RuntimeError: a deliberate failure" in completed.stderr  # not only mailed to ADMINS, who are none


# A failing view and a missing page on the embedded defaults (no DEBUG, no SECRET_KEY set).
ERROR_PAGES = """
import django
django.setup()
from django.test import Client
from django.urls import path
import studyapp.urls
def failing(request):
    raise RuntimeError("a deliberate failure")
studyapp.urls.urlpatterns.append(path("failing/", failing))
client = Client(raise_request_exception=False)
for url in ("/failing/", "/no/such/page/", "/media/stimuli/no-such-clip.mp4"):
    response = client.get(url)
    print(response.status_code, response.content.decode().replace("\\n", " "))
"""


def test_the_embedded_defaults_answer_errors_with_the_studys_plain_pages(tmp_path: Path) -> None:
    environment = {k: v for k, v in os.environ.items() if k not in DEPLOYMENT_VARIABLES}
    environment.update(DJANGO_SETTINGS_MODULE="studyapp.server.settings", STUDYAPP_VAR_DIR=str(tmp_path),
                       ALLOWED_HOSTS="testserver")
    completed = subprocess.run([sys.executable, "-c", ERROR_PAGES], cwd=REPO_ROOT, env=environment,
                               capture_output=True, text=True, timeout=60)
    server_error, missing, missing_clip = completed.stdout.splitlines()

    assert server_error.startswith("500 ") and "Something went wrong" in server_error
    assert missing.startswith("404 ") and "Not found" in missing
    assert missing_clip.startswith("404 ") and "Not found" in missing_clip
    for page in (server_error, missing, missing_clip):  # no debug page: no settings, paths or traceback
        assert "Traceback" not in page and "settings" not in page.lower() and str(tmp_path) not in page
        assert "DEBUG" not in page and "urlpatterns" not in page.lower()


def test_a_database_never_set_up_stops_manage_py_with_one_line_and_status_2(tmp_path: Path) -> None:
    environment = {k: v for k, v in os.environ.items() if k not in DEPLOYMENT_VARIABLES}
    completed = subprocess.run([sys.executable, "manage.py", "describe_study", "1"], cwd=REPO_ROOT,
                               capture_output=True, text=True, timeout=60,
                               env={**environment, "STUDYAPP_VAR_DIR": str(tmp_path)})
    assert completed.returncode == 2 and completed.stderr == (
        "manage.py: error: the database cannot answer (no such table: studyapp_study); if it was never set up, "
        "run: python manage.py migrate\n")
