"""Media files served with HTTP range requests, so videos seek, and never from outside MEDIA_ROOT."""

from pathlib import Path

import pytest

CONTENT = bytes(range(256)) * 4  # 1024 distinct-enough bytes
SIZE = len(CONTENT)


@pytest.fixture
def media_root(tmp_path: Path, settings) -> Path:
    root = tmp_path / "media"
    (root / "stimuli").mkdir(parents=True)
    (root / "stimuli" / "clip.mp4").write_bytes(CONTENT)
    (tmp_path / "secret.txt").write_text("outside the media root")
    settings.MEDIA_ROOT = root
    return root


def body(response) -> bytes:
    return b"".join(response.streaming_content)


def test_whole_file_without_range(client, media_root) -> None:
    response = client.get("/media/stimuli/clip.mp4")

    assert response.status_code == 200
    assert response["Accept-Ranges"] == "bytes"
    assert response["Content-Length"] == str(SIZE)
    assert response["Content-Type"] == "video/mp4"
    assert body(response) == CONTENT


def test_first_and_last_byte_range(client, media_root) -> None:
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE="bytes=100-199")

    assert response.status_code == 206
    assert response["Content-Range"] == f"bytes 100-199/{SIZE}"
    assert response["Content-Length"] == "100"
    assert body(response) == CONTENT[100:200]


def test_range_past_the_end_is_clipped(client, media_root) -> None:
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE=f"bytes=1000-{SIZE * 10}")

    assert response.status_code == 206
    assert response["Content-Range"] == f"bytes 1000-{SIZE - 1}/{SIZE}"
    assert body(response) == CONTENT[1000:]


def test_suffix_range_is_the_last_bytes(client, media_root) -> None:
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE="bytes=-24")

    assert response.status_code == 206
    assert response["Content-Range"] == f"bytes {SIZE - 24}-{SIZE - 1}/{SIZE}"
    assert body(response) == CONTENT[-24:]


def test_open_ended_range_runs_to_the_end(client, media_root) -> None:
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE="bytes=512-")

    assert response.status_code == 206
    assert response["Content-Range"] == f"bytes 512-{SIZE - 1}/{SIZE}"
    assert response["Content-Length"] == str(SIZE - 512)
    assert body(response) == CONTENT[512:]


@pytest.mark.parametrize("header", [f"bytes={SIZE}-", f"bytes={SIZE + 5}-{SIZE + 10}", "bytes=-0"])
def test_unsatisfiable_range_is_416(client, media_root, header: str) -> None:
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE=header)

    assert response.status_code == 416
    assert response["Content-Range"] == f"bytes */{SIZE}"


@pytest.mark.parametrize("header", ["items=0-10", "bytes=0-1,5-6", "bytes=9-3", "bytes=-"])
def test_range_it_does_not_understand_gets_the_whole_file(client, media_root, header: str) -> None:
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE=header)

    assert response.status_code == 200
    assert body(response) == CONTENT


def test_head_gives_the_headers_without_a_body(client, media_root) -> None:
    response = client.head("/media/stimuli/clip.mp4")

    assert response.status_code == 200
    assert response["Content-Length"] == str(SIZE)
    assert body(response) == b""


@pytest.mark.parametrize(
    "url",
    [
        "/media/../secret.txt",
        "/media/stimuli/../../secret.txt",
        "/media/%2e%2e/secret.txt",
        "/media//etc/passwd",
        "/media/stimuli/",
        "/media/stimuli/missing.mp4",
    ],
)
def test_paths_outside_the_media_root_or_not_files_are_404(client, media_root, url: str) -> None:
    assert client.get(url).status_code == 404


def test_symlink_leading_outside_the_media_root_is_404(client, media_root) -> None:
    (media_root / "stimuli" / "escape.txt").symlink_to(media_root.parent / "secret.txt")

    assert client.get("/media/stimuli/escape.txt").status_code == 404


def test_only_get_and_head_are_allowed(client, media_root) -> None:
    assert client.post("/media/stimuli/clip.mp4").status_code == 405
