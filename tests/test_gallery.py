"""The gallery page at /: clips from MEDIA_ROOT/gallery/index.json, or how to build them."""

import json
from pathlib import Path

import pytest

CLIPS = [
    {"file": "walk_normal_001.mp4", "title": "walk / normal / take 001", "content": "walk",
     "style": "normal", "frames": 80, "fps": 20, "sheet": "walk_normal_001.png", "poster": "walk_normal_001.poster.png"},
    {"file": "run_happy_002.mp4", "title": "run / happy / take 002", "content": "run",
     "style": "happy", "frames": 60, "fps": 30},
]


@pytest.fixture
def media_root(tmp_path: Path, settings) -> Path:
    settings.MEDIA_ROOT = tmp_path
    settings.HEALTH_TIMEOUT_S = 0.3
    return tmp_path


@pytest.fixture
def client(client, django_user_model):
    """The gallery is a researcher's page: a logged-in client."""
    client.force_login(django_user_model.objects.create_user("researcher"))
    return client


def write_index(media_root: Path, text: str) -> Path:
    folder = media_root / "gallery"
    folder.mkdir(exist_ok=True)
    (folder / "index.json").write_text(text)
    return folder


@pytest.mark.django_db
def test_without_an_index_the_page_says_how_to_build_the_gallery(client, media_root) -> None:
    response = client.get("/")

    assert response.status_code == 200
    page = response.content.decode()
    assert "make demo" in page
    assert "<video" not in page
    assert "System " in page  # the health summary sits at the top


@pytest.mark.django_db
def test_with_an_index_every_clip_gets_an_inline_player(client, media_root) -> None:
    write_index(media_root, json.dumps(CLIPS))

    page = client.get("/").content.decode()

    assert page.count('<video muted playsinline controls preload="metadata"') == 2
    assert 'src="/media/gallery/walk_normal_001.mp4"' in page
    assert 'src="/media/gallery/run_happy_002.mp4"' in page
    assert "walk / normal / take 001" in page
    assert "80 frames at 20 fps (4.0 s)" in page
    assert 'href="/media/gallery/walk_normal_001.png"' in page
    assert 'poster="/media/gallery/walk_normal_001.poster.png"' in page and page.count("poster=") == 1
    assert page.count("contact sheet") == 1
    assert "make demo" not in page


@pytest.mark.django_db
def test_a_listed_clip_is_served_seekable(client, media_root) -> None:
    folder = write_index(media_root, json.dumps(CLIPS[:1]))
    (folder / "walk_normal_001.mp4").write_bytes(b"\0" * 4096)

    response = client.get("/media/gallery/walk_normal_001.mp4", HTTP_RANGE="bytes=0-1023")

    assert response.status_code == 206
    assert response["Content-Range"] == "bytes 0-1023/4096"


@pytest.mark.django_db
@pytest.mark.parametrize("text", ["{not json", '{"file": "a.mp4"}', '[{"title": "no file"}]'])
def test_a_broken_index_is_reported_not_a_server_error(client, media_root, text: str) -> None:
    write_index(media_root, text)

    response = client.get("/")

    assert response.status_code == 200
    assert "could not be read" in response.content.decode()


@pytest.mark.django_db
def test_the_gallery_and_the_health_page_need_a_login_and_health_json_does_not(media_root) -> None:
    from django.test import Client

    anonymous = Client()
    for page in ("/", "/health/"):
        response = anonymous.get(page)
        assert response.status_code == 302 and response["Location"].startswith("/login/"), page
    assert anonymous.get("/health.json").status_code in (200, 503)  # container health checks read it
