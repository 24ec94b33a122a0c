"""The health page and JSON: a real database query, and a dead broker reported quickly."""

import socket
import time

import pytest

from studyapp.server.celery import app as celery_app


@pytest.fixture
def closed_port() -> int:
    # The kernel hands out a free port; closing the socket leaves nothing listening.
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def broker_down(monkeypatch: pytest.MonkeyPatch, closed_port: int) -> None:
    monkeypatch.setitem(celery_app.conf, "broker_url", f"redis://127.0.0.1:{closed_port}/0")
    monkeypatch.setitem(celery_app.conf, "broker_transport_options", {})
    monkeypatch.setitem(celery_app.conf, "broker_transport", None)  # the URL's scheme says which


@pytest.fixture
def client(client, django_user_model):
    """The health page is a researcher's page (the JSON is public): a logged-in client."""
    client.force_login(django_user_model.objects.create_user("researcher"))
    return client


@pytest.fixture
def short_timeout(settings) -> None:
    settings.HEALTH_TIMEOUT_S = 0.3


@pytest.mark.django_db
def test_health_json_reports_the_database_from_a_real_query(client, short_timeout) -> None:
    response = client.get("/health.json")

    assert response.status_code == 200
    report = response.json()
    assert report["database"] == {"ok": True, "detail": "sqlite"}
    assert report["status"] in {"ok", "degraded"}
    assert set(report["workers"]) == {"count", "names"}


@pytest.mark.django_db
def test_health_page_is_html_with_each_check(client, short_timeout) -> None:
    response = client.get("/health/")

    assert response.status_code == 200
    assert response["Content-Type"].startswith("text/html")
    for label in (b"Database", b"Broker", b"Live workers"):
        assert label in response.content


@pytest.mark.django_db
def test_broker_down_is_reported_as_degraded_within_two_seconds(client, broker_down) -> None:
    started = time.monotonic()
    response = client.get("/health.json")
    elapsed = time.monotonic() - started

    assert elapsed < 2.0
    # The web process still works without its broker, so it stays 200.
    assert response.status_code == 200
    report = response.json()
    assert report["status"] == "degraded"
    assert report["broker"]["ok"] is False
    assert "refused" in report["broker"]["detail"].lower()
    assert report["workers"] == {"count": 0, "names": []}


@pytest.mark.django_db
def test_health_page_with_broker_down_also_answers_quickly(client, broker_down) -> None:
    started = time.monotonic()
    response = client.get("/health/")

    assert time.monotonic() - started < 2.0
    assert b"Health: degraded" in response.content
