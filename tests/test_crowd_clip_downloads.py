"""The crowd benchmark's clip downloads (benchmarks/bench_study_clips.py) with a handful of watching
participants on short clips: through the proxy every clip byte the pages named arrives and
gunicorn writes none of them, and without it (the code before) gunicorn writes them all, which
shows that the count of gunicorn's bytes sees them when they are there."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from benchmarks.bench_study_clips import measure_clip_crowd

pytestmark = pytest.mark.slow

PARTICIPANTS, CLIP_SECONDS = 3, 0.2


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    """The study's clip: bytes no two downloads could agree on by chance."""
    path = tmp_path_factory.mktemp("clip") / "clip.mp4"
    path.write_bytes(os.urandom(300_000))
    return path


def test_watching_participants_get_every_clip_byte_through_the_proxy_and_none_from_gunicorn(clip):
    row = measure_clip_crowd("proxy", PARTICIPANTS, 0.0, clip, clip_seconds=CLIP_SECONDS)

    assert row["finished"] == PARTICIPANTS and row["errors"] == [] and row["exactly_stored"]
    # Every clip of the 20 rated, the 2 practice ones and the device check's, each once.
    assert row["clips"] >= PARTICIPANTS * 22 and row["wrong_clips"] == 0
    assert row["clip_bytes_served"] == row["clip_bytes_expected"] == row["clips"] * 300_000
    assert row["gunicorn_media_bytes"] == 0 and row["gunicorn_media_share"] == 0.0


def test_without_the_proxy_gunicorn_writes_every_clip_byte_itself(clip):
    row = measure_clip_crowd("gunicorn", PARTICIPANTS, 0.0, clip, clip_seconds=CLIP_SECONDS)

    assert row["finished"] == PARTICIPANTS and row["clip_bytes_served"] == row["clip_bytes_expected"] > 0
    assert row["gunicorn_media_bytes"] == row["clip_bytes_served"] and row["gunicorn_media_share"] == 1.0
