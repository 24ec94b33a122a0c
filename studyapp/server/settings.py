"""Django settings for the study app, read from the environment.

Every value has an embedded default that runs with no servers (see `embedded.py`);
`compose.yaml` sets the production values. Nothing here is edited by hand to move
from the demo to production.
"""

import os
from pathlib import Path

import dj_database_url
from django.core.exceptions import ImproperlyConfigured

from studyapp.server.embedded import (
    FILESYSTEM_BROKER_URL,
    FILESYSTEM_TRANSPORT,
    filesystem_broker_options,
    filesystem_result_backend_url,
    is_filesystem_broker,
    stored_secret_key,
)
from studyapp.server.env import env_bool, env_float, env_list, env_str
from studyapp.server.media_bucket import bucket_storage

BASE_DIR = Path(__file__).resolve().parents[2]
VAR_DIR = Path(env_str("STUDYAPP_VAR_DIR", str(BASE_DIR / "var"))).resolve()
VAR_DIR.mkdir(parents=True, exist_ok=True)

# Off unless a developer sets DEBUG=1: its error pages show settings and paths to anyone,
# participants included.
DEBUG = env_bool("DEBUG", False)

SECRET_KEY = env_str("SECRET_KEY", "") or stored_secret_key(VAR_DIR)

ALLOWED_HOSTS = env_list("ALLOWED_HOSTS", ["localhost", "127.0.0.1", "[::1]"])
CSRF_TRUSTED_ORIGINS = env_list("CSRF_TRUSTED_ORIGINS", [])

# Served over HTTPS through a TLS-terminating proxy. Cookies are then Secure and are also
# sent inside another site's frame (SameSite=None), which MTurk needs: it shows the
# participant pages in an iframe of its own site.
HTTPS = env_bool("HTTPS", False)
if HTTPS:
    SESSION_COOKIE_SECURE = CSRF_COOKIE_SECURE = True
    SESSION_COOKIE_SAMESITE = CSRF_COOKIE_SAMESITE = "None"
    SECURE_PROXY_SSL_HEADER = ("HTTP_X_FORWARDED_PROTO", "https")

INSTALLED_APPS = [
    "django.contrib.admin",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "studyapp",
]

MIDDLEWARE = [
    "studyapp.server.uploads.upload_limit.UploadLimitMiddleware",  # before anything reads the body
    "studyapp.server.uploads.unreadable_forms.UnreadableFormMiddleware",  # a body no form parse can read: 400, not 500
    "django.middleware.security.SecurityMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "studyapp.server.uploads.null_characters.RefuseNullCharactersMiddleware",  # text PostgreSQL could not hold
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
    "studyapp.server.broken_rows.BrokenRowMiddleware",  # a row the code cannot read: 409 naming it, not 500
]

ROOT_URLCONF = "studyapp.urls"
CSRF_FAILURE_VIEW = "studyapp.participants.views.csrf_failure"  # a plain page, whatever DEBUG says
WSGI_APPLICATION = "studyapp.server.wsgi.application"

TEMPLATES = [
    {
        "BACKEND": "django.template.backends.django.DjangoTemplates",
        "DIRS": [],
        "APP_DIRS": True,
        "OPTIONS": {
            "context_processors": [
                "django.template.context_processors.request",
                "django.contrib.auth.context_processors.auth",
                "django.contrib.messages.context_processors.messages",
            ],
        },
    },
]

DATABASES = {
    "default": dj_database_url.parse(
        env_str("DATABASE_URL", f"sqlite:///{VAR_DIR / 'db.sqlite3'}"),
        conn_max_age=60,
        conn_health_checks=True,
    )
}
if DATABASES["default"]["ENGINE"].endswith("postgresql"):
    # Values travel apart from the statement text, so the few statements that every page
    # runs are the same text each time, and psycopg prepares one the fifth time a
    # connection runs it: PostgreSQL then skips parsing and planning it. At saturation
    # this took a quarter of the database's CPU per rating away (benchmarks/bench_study.py).
    DATABASES["default"].setdefault("OPTIONS", {}).update(server_side_binding=True, prepare_threshold=5)

if DATABASES["default"]["ENGINE"] == "django.db.backends.sqlite3":
    # Writers take the lock when their transaction begins, so the read-then-write of
    # assigning clips cannot interleave between two participants; waiters queue up.
    # WAL: readers never wait for the writer, and a commit appends to the log instead of
    # rewriting pages behind a journal with several fsyncs (35 ms each on this machine's
    # disk, which made a crowd's writers time out). synchronous=NORMAL syncs at
    # checkpoints: a crashed server process loses nothing, a power cut the last moments.
    # The writers of one server process take turns (``sqlite_backend``) rather than poll.
    DATABASES["default"]["ENGINE"] = "studyapp.server.db.sqlite_backend"
    DATABASES["default"].setdefault("OPTIONS", {}).update({
        "transaction_mode": "IMMEDIATE", "timeout": 30,
        "init_command": "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;"})
    # Tests use a file, not memory, so that a live server's threads get connections of
    # their own and concurrency tests meet the same locking as production.
    DATABASES["default"]["TEST"] = {"NAME": str(VAR_DIR / "test-db.sqlite3")}
DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

# Researcher pages use Django's auth with a login page of their own; researchers need
# not be staff (the admin, for staff, shows each researcher only their own studies).
LOGIN_URL = "login"
LOGIN_REDIRECT_URL = "study-list"
LOGOUT_REDIRECT_URL = "login"

# Warnings and errors (a 500's traceback among them) go to stderr whatever DEBUG says:
# Django alone would mail them to ADMINS when DEBUG is off, and a container has none.
# What is sent to a crowd platform's API (approvals, rejections, bonuses) is logged too.
LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "handlers": {"stderr": {"class": "logging.StreamHandler", "level": "INFO"}},
    "loggers": {"studyapp.platforms": {"level": "INFO"}},
    "root": {"handlers": ["stderr"], "level": "WARNING"},
}

LANGUAGE_CODE = "en-us"
TIME_ZONE = "UTC"
USE_I18N = True
USE_TZ = True

STATIC_URL = "static/"
STATIC_ROOT = Path(env_str("STATIC_ROOT", str(VAR_DIR / "static")))
MEDIA_URL = "media/"
MEDIA_ROOT = Path(env_str("MEDIA_ROOT", str(VAR_DIR / "media")))

# With no reverse proxy in front (the demo, and compose as shipped) the app serves
# media and collected static files itself, with range support so videos seek.
# Turn it off when a proxy serves /media/ and /static/ from the same folders.
SERVE_FILES = env_bool("SERVE_FILES", True)
# Behind the proxy of compose.yaml (deploy/Caddyfile): the app decides who may see a media
# file and answers with an X-Accel-Redirect header, the proxy sends the bytes (ranges,
# caching); a clip's address is signed and stops working CLIP_URL_LIFETIME_S after its
# page (studyapp.server.clip_urls).
MEDIA_ACCEL = env_bool("MEDIA_ACCEL", False)
CLIP_URL_LIFETIME_S = env_float("CLIP_URL_LIFETIME_S", 3600.0)
if CLIP_URL_LIFETIME_S < 60:
    raise ImproperlyConfigured(f"CLIP_URL_LIFETIME_S={CLIP_URL_LIFETIME_S:g} is under a minute: "
                               "clips would stop playing on the pages that show them")
# The clips in an S3-compatible bucket (s3://BUCKET or s3://BUCKET/PREFIX) instead of MEDIA_ROOT:
# workers upload them, and a participant's clip request is redirected to an expiring presigned
# address of the bucket (studyapp.server.media_bucket). MEDIA_BUCKET_ENDPOINT_URL names a server
# other than AWS's; the key is AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY as boto3 reads them.
MEDIA_BUCKET_URL = env_str("MEDIA_BUCKET_URL", "")
MEDIA_BUCKET_ENDPOINT_URL = env_str("MEDIA_BUCKET_ENDPOINT_URL", "")
STORAGES = {
    "default": (bucket_storage(MEDIA_BUCKET_URL, MEDIA_BUCKET_ENDPOINT_URL, CLIP_URL_LIFETIME_S) if MEDIA_BUCKET_URL
                else {"BACKEND": "django.core.files.storage.FileSystemStorage"}),
    "staticfiles": {"BACKEND": "django.contrib.staticfiles.storage.StaticFilesStorage"},
}

CELERY_BROKER_URL = env_str("CELERY_BROKER_URL", FILESYSTEM_BROKER_URL)
if is_filesystem_broker(CELERY_BROKER_URL):
    CELERY_BROKER_TRANSPORT = FILESYSTEM_TRANSPORT
    CELERY_BROKER_TRANSPORT_OPTIONS = filesystem_broker_options(VAR_DIR)
CELERY_RESULT_BACKEND = env_str("CELERY_RESULT_BACKEND", "") or filesystem_result_backend_url(VAR_DIR)
CELERY_BROKER_CONNECTION_RETRY_ON_STARTUP = True
CELERY_TASK_TRACK_STARTED = True
CELERY_RESULT_EXPIRES = 24 * 3600
# One deployment's web processes and workers share a queue; several deployments (or
# test runs) on one Redis keep apart by naming their own.
CELERY_TASK_DEFAULT_QUEUE = env_str("CELERY_QUEUE", "celery")
# Sampling a model and rendering clips may go to different queues, so that a GPU
# machine's worker (-Q on the sampling queue) takes the sampling alone; both default to
# the one queue. STUDY_DEVICE is where a worker samples: auto (CUDA when present), cpu, cuda.
STUDY_SAMPLE_QUEUE = env_str("STUDY_SAMPLE_QUEUE", CELERY_TASK_DEFAULT_QUEUE)
STUDY_RENDER_QUEUE = env_str("STUDY_RENDER_QUEUE", CELERY_TASK_DEFAULT_QUEUE)
STUDY_DEVICE = env_str("STUDY_DEVICE", "auto")
if STUDY_DEVICE not in ("auto", "cpu", "cuda"):
    raise ImproperlyConfigured(f"STUDY_DEVICE={STUDY_DEVICE!r} is not one of auto, cpu, cuda")
# A sampling task samples its system's controls in batches of at most this many clips,
# one call of the model per batch (per length, where controls differ in length): memory
# grows with the batch (each row holds its clip's noise, poses and recurrent state).
_sample_batch = env_float("STUDY_SAMPLE_BATCH", 64)
if _sample_batch < 1 or _sample_batch != int(_sample_batch):
    raise ImproperlyConfigured(f"STUDY_SAMPLE_BATCH={_sample_batch:g} is not a whole number of at least 1")
STUDY_SAMPLE_BATCH = int(_sample_batch)
# Every worker touches the rows of the tasks it holds each STUDY_HEARTBEAT_S; a row untouched
# for STUDY_LOST_AFTER_S whose message is not waiting in the broker lost its task with its
# worker and is sent again (studyapp.stimuli.lost_tasks). Three missed beats and some.
STUDY_HEARTBEAT_S = env_float("STUDY_HEARTBEAT_S", 10.0)
STUDY_LOST_AFTER_S = env_float("STUDY_LOST_AFTER_S", 45.0)
if not 0 < 3 * STUDY_HEARTBEAT_S < STUDY_LOST_AFTER_S:
    raise ImproperlyConfigured(f"STUDY_LOST_AFTER_S={STUDY_LOST_AFTER_S:g} must exceed three heartbeats "
                               f"(STUDY_HEARTBEAT_S={STUDY_HEARTBEAT_S:g}, which must be positive)")

# Uploaded checkpoints live here, named by content digest; never under MEDIA_ROOT,
# which is served to the public.
CHECKPOINT_ROOT = Path(env_str("CHECKPOINT_ROOT", str(VAR_DIR / "checkpoints")))
# Checkpoints every researcher may name by digest in a definition, read-only (studyapp.ownership):
# by default the project's committed models, which the demo's study is made of. Any other
# checkpoint is a researcher's own, named only by them.
SHARED_CHECKPOINTS = Path(env_str("SHARED_CHECKPOINTS", str(BASE_DIR / "models")))
# The motion capture that held-out controls and natural (NAT) clips are read from: one
# folder of BVH files, or several joined with ":" (by default both Bandai-Namco folders,
# the data the committed MoGlow was trained on).
MOTION_DATA = env_str("MOTION_DATA", os.pathsep.join(
    str(BASE_DIR.parent / "shared" / "data" / name) for name in ("bandai-namco-1", "bandai-namco-2-locomotion")))
# The paper-sized MoGlow is about 300 MB in float32.
MAX_CHECKPOINT_UPLOAD_BYTES = int(env_float("MAX_CHECKPOINT_UPLOAD_MB", 500) * 1_000_000)
MAX_VIDEO_UPLOAD_BYTES = int(env_float("MAX_VIDEO_UPLOAD_MB", 50) * 1_000_000)
MAX_MOTION_UPLOAD_BYTES = int(env_float("MAX_MOTION_UPLOAD_MB", 200) * 1_000_000)  # a zip, and what it unpacks to
# A study bundle (studyapp.bundles): the zip, and what it unpacks to; each file in it is held
# to the limit of its kind (checkpoints, videos, records, and the motion limit for the rest).
MAX_BUNDLE_UPLOAD_BYTES = int(env_float("MAX_BUNDLE_UPLOAD_MB", 1000) * 1_000_000)
# A bundle's records (study.json, participants.json, ...), each read whole into memory: a
# rating with its page is about 575 bytes of participants.json, so this is about 85,000 ratings.
MAX_RECORD_UPLOAD_BYTES = int(env_float("MAX_RECORD_UPLOAD_MB", 50) * 1_000_000)
# Large uploads go to a temporary file, not memory.
FILE_UPLOAD_MAX_MEMORY_SIZE = 5_000_000

# Ratings tables uploaded for analysis; 100,000 ratings are about 10 MB of CSV.
MAX_RATINGS_UPLOAD_BYTES = int(env_float("MAX_RATINGS_UPLOAD_MB", 50) * 1_000_000)
DATA_UPLOAD_MAX_MEMORY_SIZE = MAX_RATINGS_UPLOAD_BYTES

# Bounds on each health probe, so a dead broker never holds a page for long.
HEALTH_TIMEOUT_S = env_float("HEALTH_TIMEOUT_S", 1.0)

# The crowd platforms' APIs (``studyapp.platforms``): Prolific's, and MTurk's requester
# API, its sandbox used unless the researcher asks for the real one.
PROLIFIC_API_URL = env_str("PROLIFIC_API_URL", "https://api.prolific.com")
MTURK_API_URL = env_str("MTURK_API_URL", "https://mturk-requester.us-east-1.amazonaws.com")
MTURK_SANDBOX_API_URL = env_str("MTURK_SANDBOX_API_URL", "https://mturk-requester-sandbox.us-east-1.amazonaws.com")
