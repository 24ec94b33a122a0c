"""The environment variables that configure the study app, and typed readers for them.

Settings read every deployment choice from the environment so that the demo and
production run the same code; these helpers keep the parsing rules in one place
and fail loudly on a value they cannot understand rather than guessing.

`VARIABLES` declares every variable the project's code reads, once, with its default as
a reader sees it and what it does: docs/reference/environment.md is generated from it
(`make docs-reference`), and tests/test_docs_reference.py checks that each read in the
code names a declared variable, each declared one is read, and each default written in
a reader's call is the one declared. A new variable: read it with a reader below (or,
in `generation`, which cannot import the study app, with os.environ), declare it here,
and run `make docs-reference`.
"""

import os
from dataclasses import dataclass

from django.core.exceptions import ImproperlyConfigured



@dataclass(frozen=True)
class Variable:
    name: str
    default: str  # as the reference shows it: a reader's literal default, or what a computed one is
    help: str
    group: str


_STUDY = "The study app (web processes and workers)"
_UPLOADS = "Upload limits"
_PLATFORMS = "Crowd platforms"
_DEMO = "make demo"
_DATA = "Motion data (the study app and the generation command line)"

VARIABLES: tuple[Variable, ...] = (
    Variable("STUDYAPP_VAR_DIR", "var/ in the repository",
             "the folder of the embedded defaults: database, broker, media, checkpoints, dataset cache", _STUDY),
    Variable("DEBUG", "off", "Django's debug pages; a developer's setting only (they show settings to anyone)", _STUDY),
    Variable("SECRET_KEY", "a random key made once in $STUDYAPP_VAR_DIR/secret-key",
             "signs sessions and encrypts the platforms' tokens; production must set it", _STUDY),
    Variable("ALLOWED_HOSTS", "localhost,127.0.0.1,[::1]", "the host names the server answers to, comma-separated",
             _STUDY),
    Variable("CSRF_TRUSTED_ORIGINS", "(none)",
             "origins (https://study.example.org) whose forms are accepted, when a proxy's address differs from "
             "ALLOWED_HOSTS", _STUDY),
    Variable("HTTPS", "off",
             "served through a TLS proxy: Secure cookies, also sent in another site's frame (MTurk needs it)",
             _STUDY),
    Variable("DATABASE_URL", "SQLite at $STUDYAPP_VAR_DIR/db.sqlite3",
             "the database, as a URL (postgres://user:password@host:5432/study in production)", _STUDY),
    Variable("STATIC_ROOT", "$STUDYAPP_VAR_DIR/static", "where collectstatic puts the pages' CSS and scripts", _STUDY),
    Variable("MEDIA_ROOT", "$STUDYAPP_VAR_DIR/media", "rendered clips, the gallery and reports; shared by web and worker",
             _STUDY),
    Variable("SERVE_FILES", "on",
             "the app serves /media/ and /static/ itself (with range requests); off when a proxy serves them", _STUDY),
    Variable("CELERY_BROKER_URL", "kombu's filesystem transport under $STUDYAPP_VAR_DIR/broker",
             "the task queue's broker (redis://redis:6379/0 in production)", _STUDY),
    Variable("CELERY_RESULT_BACKEND", "files under $STUDYAPP_VAR_DIR",
             "where task results go (redis://redis:6379/1 in production)", _STUDY),
    Variable("CELERY_QUEUE", "celery", "the queue one deployment's processes share; several deployments on one Redis "
             "name their own", _STUDY),
    Variable("STUDY_SAMPLE_QUEUE", "$CELERY_QUEUE", "the queue of sampling tasks (a GPU machine's worker takes it "
             "with -Q)", _STUDY),
    Variable("STUDY_RENDER_QUEUE", "$CELERY_QUEUE", "the queue of rendering tasks", _STUDY),
    Variable("STUDY_DEVICE", "auto", "where a worker samples: auto (CUDA when present), cpu or cuda", _STUDY),
    Variable("STUDY_SAMPLE_BATCH", "64", "the most clips a sampling task samples in one call of the model", _STUDY),
    Variable("STUDY_HEARTBEAT_S", "10", "seconds between a worker's touches of the tasks it holds", _STUDY),
    Variable("STUDY_LOST_AFTER_S", "45",
             "seconds after which an untouched task whose message is gone is sent again (over three heartbeats)",
             _STUDY),
    Variable("MEDIA_ACCEL", "off",
             "behind compose's proxy: the app decides who may see a media file and answers with an X-Accel-Redirect "
             "header, the proxy sends the bytes; clip addresses are signed and expire", _STUDY),
    Variable("CLIP_URL_LIFETIME_S", "3600",
             "seconds a signed clip address (MEDIA_ACCEL, or the bucket's presigned one) keeps working; at least 60",
             _STUDY),
    Variable("MEDIA_BUCKET_URL", "unset: clips under MEDIA_ROOT",
             "s3://BUCKET or s3://BUCKET/PREFIX: clips in an S3-compatible bucket, participants redirected to "
             "presigned addresses (the key: AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY, as boto3 reads them)", _STUDY),
    Variable("MEDIA_BUCKET_ENDPOINT_URL", "unset: AWS", "the S3 server's address when it is not AWS's", _STUDY),
    Variable("STUDY_RESEARCHER_PASSWORD", "unset: asked at the prompt",
             "the password `manage.py create_researcher` gives the new login when --password-file is not given",
             _STUDY),
    Variable("SHARED_CHECKPOINTS", "models/ in the repository",
             "the checkpoints every researcher may name in a study definition, read-only (the committed demo "
             "models); any other checkpoint must be the researcher's own", _STUDY),
    Variable("CHECKPOINT_ROOT", "$STUDYAPP_VAR_DIR/checkpoints",
             "uploaded checkpoints, named by digest; never under MEDIA_ROOT, which is public", _STUDY),
    Variable("HEALTH_TIMEOUT_S", "1", "the bound on each probe of the health page (/health/)", _STUDY),
    Variable("MAX_CHECKPOINT_UPLOAD_MB", "500", "the largest checkpoint the systems page accepts", _UPLOADS),
    Variable("MAX_VIDEO_UPLOAD_MB", "50", "the largest pre-rendered video a system may upload", _UPLOADS),
    Variable("MAX_MOTION_UPLOAD_MB", "200", "the largest zip of motion files (and what it unpacks to)", _UPLOADS),
    Variable("MAX_BUNDLE_UPLOAD_MB", "1000", "the largest study bundle (and what it unpacks to)", _UPLOADS),
    Variable("MAX_RECORD_UPLOAD_MB", "50", "the largest JSON record file inside a study bundle (participants.json, "
             "...), checked before it is read", _UPLOADS),
    Variable("MAX_RATINGS_UPLOAD_MB", "50", "the largest ratings table for analysis, and any other form", _UPLOADS),
    Variable("PROLIFIC_API_URL", "https://api.prolific.com", "Prolific's API", _PLATFORMS),
    Variable("MTURK_API_URL", "https://mturk-requester.us-east-1.amazonaws.com", "MTurk's requester API", _PLATFORMS),
    Variable("MTURK_SANDBOX_API_URL", "https://mturk-requester-sandbox.us-east-1.amazonaws.com",
             "MTurk's sandbox, used unless the researcher asks for the real one", _PLATFORMS),
    Variable("MOTION_DATA", "../shared/data/bandai-namco-1:../shared/data/bandai-namco-2-locomotion",
             "the motion capture: one BVH folder, or several joined with ':' (held-out controls, NAT clips, the "
             "demo's dataset; the generation commands' default --data)", _DATA),
    Variable("MOTION_CACHE_DIR", "$STUDYAPP_VAR_DIR/cache", "where built datasets are cached", _DATA),
    Variable("DEMO_PORT", "8000", "the port the demo serves on", _DEMO),
    Variable("DEMO_HOST", "0.0.0.0",
             "where the demo listens; 0.0.0.0 (every interface) prints links with this machine's network address, "
             "127.0.0.1 keeps it to this machine", _DEMO),
    Variable("DEMO_TRAIN", "off",
             "train the demo's own models where a committed one is missing, changed or learnt from other data "
             "(minutes for RNN, VAE and BAD, about an hour for MoGlow)", _DEMO),
)
DECLARED = {variable.name: variable for variable in VARIABLES}

_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


def env_str(name: str, default: str) -> str:
    """The variable's value, or `default` when it is unset or empty."""
    return os.environ.get(name) or default


def env_bool(name: str, default: bool) -> bool:
    """A yes/no variable; anything but the usual spellings is an error."""
    raw = os.environ.get(name, "").strip().lower()
    if not raw:
        return default
    if raw in _TRUE:
        return True
    if raw in _FALSE:
        return False
    raise ImproperlyConfigured(f"{name}={raw!r} is not a boolean (use 1/0, true/false, yes/no, on/off)")


def env_list(name: str, default: list[str]) -> list[str]:
    """A comma-separated variable, blanks dropped."""
    raw = os.environ.get(name)
    if raw is None or not raw.strip():
        return list(default)
    return [item.strip() for item in raw.split(",") if item.strip()]


def env_float(name: str, default: float) -> float:
    """A number of seconds or similar."""
    raw = os.environ.get(name, "").strip()
    if not raw:
        return default
    try:
        return float(raw)
    except ValueError:
        raise ImproperlyConfigured(f"{name}={raw!r} is not a number") from None
