"""compose.yaml has the production shape: four services, health checks, a shared media volume."""

import re
from pathlib import Path

import yaml

REPO_ROOT = Path(__file__).resolve().parent.parent


def load_compose() -> dict:
    return yaml.safe_load((REPO_ROOT / "compose.yaml").read_text())


def test_every_service_has_a_health_check() -> None:
    services = load_compose()["services"]

    assert {"web", "worker", "redis", "postgres"} <= services.keys()
    checks = {name: " ".join(services[name]["healthcheck"]["test"]) for name in ("web", "worker", "redis", "postgres")}
    assert "redis-cli ping" in checks["redis"]
    assert "pg_isready" in checks["postgres"]
    assert "/health.json" in checks["web"]
    assert "celery -A studyapp inspect ping" in checks["worker"]


def test_web_and_worker_run_the_app_against_postgres_and_redis() -> None:
    services = load_compose()["services"]
    web, worker = services["web"], services["worker"]

    assert web["command"][:2] == ["gunicorn", "studyapp.server.wsgi"]
    assert worker["command"][:4] == ["celery", "-A", "studyapp", "worker"]
    for service in (web, worker):
        environment = service["environment"]
        assert environment["DATABASE_URL"].startswith("postgres://")
        assert environment["CELERY_BROKER_URL"].startswith("redis://redis:")
        assert environment["DEBUG"] == "0"
        assert service["build"] == "."


def test_web_and_worker_share_media_checkpoints_and_the_motion_data() -> None:
    compose = load_compose()
    services = compose["services"]

    assert {"media", "var"} <= compose["volumes"].keys()
    mounts = {name: services[name]["volumes"] for name in ("web", "worker")}
    assert mounts["web"] == mounts["worker"]
    assert {"media:/data/media", "var:/data/var"} <= set(mounts["web"])
    assert any(mount.endswith(":/data/motion:ro") for mount in mounts["web"])
    environment = services["web"]["environment"]
    assert environment["MEDIA_ROOT"] == "/data/media"
    assert environment["STUDYAPP_VAR_DIR"] == "/data/var"  # where uploaded checkpoints are stored
    assert environment["MOTION_DATA"] == "${MOTION_FOLDERS:-/data/motion}"  # one folder or several, ":"-joined


def test_redis_keeps_the_queue_on_disk_in_its_volume() -> None:
    compose = load_compose()
    redis = compose["services"]["redis"]

    command = redis["command"]
    assert command[0] == "redis-server" and command[command.index("--appendonly") + 1] == "yes"
    assert "redis-data:/data" in redis["volumes"] and "redis-data" in compose["volumes"]


def test_backups_have_a_folder_and_the_image_has_the_dump_programs() -> None:
    compose = load_compose()

    assert "${BACKUP_DIR:-backups}:/data/backups" in compose["services"]["web"]["volumes"]
    assert "backups" in compose["volumes"]
    dockerfile = (REPO_ROOT / "Dockerfile").read_text()
    assert '"postgresql-client-${POSTGRES_MAJOR}"' in dockerfile and "/data/backups" in dockerfile
    # pg_dump and pg_restore of the server's own major version (compose's postgres image).
    server_major = compose["services"]["postgres"]["image"].split(":")[1].split("-")[0].split(".")[0]
    assert f"ARG POSTGRES_MAJOR={server_major}\n" in dockerfile


def test_app_services_wait_for_healthy_dependencies() -> None:
    services = load_compose()["services"]

    for name in ("web", "worker"):
        depends_on = services[name]["depends_on"]
        assert depends_on["postgres"]["condition"] == "service_healthy"
        assert depends_on["redis"]["condition"] == "service_healthy"
        assert depends_on["migrate"]["condition"] == "service_completed_successfully"


def test_dockerfile_pins_torch_before_installing_the_project() -> None:
    dockerfile = (REPO_ROOT / "Dockerfile").read_text()

    assert dockerfile.startswith("# ") and "FROM python:3.11-slim" in dockerfile
    assert dockerfile.index("RUN pip install torch==2.13.0") < dockerfile.index("RUN pip install .\n")


def test_the_proxy_alone_faces_the_internet_with_tls_and_sends_the_media_itself() -> None:
    compose = load_compose()
    services = compose["services"]
    proxy = services["proxy"]

    assert proxy["image"].startswith("caddy:2")
    assert {"80:80", "443:443"} <= set(proxy["ports"])
    assert "ports" not in services["web"] and services["web"]["expose"] == ["8000"]
    assert "./deploy/Caddyfile:/etc/caddy/Caddyfile:ro" in proxy["volumes"]
    assert {"media:/srv/media:ro", "static:/srv/static:ro", "caddy-data:/data"} <= set(proxy["volumes"])
    environment = proxy["environment"]
    assert environment["STUDY_UPSTREAM"] == "web:8000" and environment["STUDY_DOMAIN"] == "${STUDY_DOMAIN:-localhost}"
    assert (environment["MEDIA_ROOT"], environment["STATIC_ROOT"]) == ("/srv/media", "/srv/static")
    assert proxy["depends_on"]["web"]["condition"] == "service_healthy"
    app = services["web"]["environment"]
    assert app["HTTPS"] == "1" and app["MEDIA_ACCEL"] == "1"  # the app answers X-Accel-Redirect, signs clip URLs
    assert "${STUDY_DOMAIN:-localhost}" in app["ALLOWED_HOSTS"] and "127.0.0.1" in app["ALLOWED_HOSTS"]


def test_the_static_files_are_collected_into_the_volume_the_proxy_sends_them_from() -> None:
    services = load_compose()["services"]
    static = services["static"]

    assert static["command"][:3] == ["python", "manage.py", "collectstatic"]
    assert static["volumes"] == [f"static:{static['environment']['STATIC_ROOT']}"]
    assert services["proxy"]["depends_on"]["static"]["condition"] == "service_completed_successfully"


def test_every_setting_the_caddyfile_reads_is_given_by_compose() -> None:
    caddyfile = (REPO_ROOT / "deploy" / "Caddyfile").read_text()
    read = set(re.findall(r"\{\$([A-Z_]+)(?::[^}]*)?\}", caddyfile))
    given = set(load_compose()["services"]["proxy"]["environment"])

    assert read - given == {"STUDY_HTTP_PORT", "STUDY_HTTPS_PORT"}  # their defaults, 80 and 443, are compose's ports
    assert "X-Accel-Redirect" in caddyfile and "/_accel/media" in caddyfile


def test_gunicorn_keeps_an_idle_connection_longer_than_the_proxy_does() -> None:
    # Else the proxy may send a rating on a connection gunicorn has just closed and answer
    # the participant 502 Bad Gateway (a POST is not retried): at 1,000 watching
    # participants 62 to 312 were stopped so before gunicorn's keep-alive outlasted Caddy's.
    command = load_compose()["services"]["web"]["command"]
    gunicorn_s = float(command[command.index("--keep-alive") + 1])
    caddyfile = (REPO_ROOT / "deploy" / "Caddyfile").read_text()
    transport = re.search(r"transport http \{[^}]*?\bkeepalive (\d+)s\b", caddyfile)

    assert transport, "the Caddyfile's reverse_proxy names no keepalive for its upstream connections"
    assert gunicorn_s > float(transport.group(1)) + 5
