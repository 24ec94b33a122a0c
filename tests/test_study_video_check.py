"""The study uses a stimulus video only once it has decoded whole: an uploaded video cut
short (whose first frames still decode) is refused naming the file, and a rendered clip
whose file falls short of its motion fails its task with the reason and leaves no video.
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile

from generation.motion.bvh import load_motion
from generation.motion.types import Motion
from generation.render import render_video
from studyapp.models import ControlSignal, Stimulus, Study, System
from studyapp.stimuli import clips
from studyapp.stimuli.sources import Clip
from studyapp.tasks import generate_stimulus

SIZE = (160, 120)


@pytest.fixture(scope="module")
def walk(clip_path) -> Motion:
    """Two seconds of a real walk (30 fps in the file)."""
    motion = load_motion(clip_path("walk_normal_001"))
    return Motion(motion.positions[:60], motion.fps, motion.skeleton)


@pytest.fixture(scope="module")
def rendered(walk, tmp_path_factory) -> Path:
    return render_video(walk, tmp_path_factory.mktemp("videos") / "walk.mp4", size=SIZE)


@pytest.fixture
def media(settings, tmp_path) -> Path:
    settings.MEDIA_ROOT = tmp_path / "media"
    return settings.MEDIA_ROOT


@pytest.mark.django_db
def test_an_uploaded_video_cut_in_half_is_refused_naming_it_and_stores_nothing(client, rendered, media):
    owner = User.objects.create_user("researcher")
    client.force_login(owner)
    study = Study.objects.create(owner=owner, title="Gait")
    data = rendered.read_bytes()

    response = client.post(f"/studies/{study.pk}/systems/", {"action": "videos", "name": "BAD", "videos": [
        SimpleUploadedFile("half.mp4", data[:len(data) // 2])]})

    assert response.status_code == 400
    page = html.unescape(response.content.decode())
    assert "half.mp4: its video does not decode to its end: cut short: the file declares 2 s but its frames end" in page
    assert not System.objects.exists() and not Stimulus.objects.exists()
    assert not any(Path(media).rglob("*.mp4"))
    whole = client.post(f"/studies/{study.pk}/systems/", {"action": "videos", "name": "BAD", "videos": [
        SimpleUploadedFile("whole.mp4", data)]})
    assert whole.status_code == 302 and Stimulus.objects.get().duration_s == 2.0


class OneWalk:
    """A source of motion that answers every stimulus with the same real walk."""

    def __init__(self, motion: Motion) -> None:
        self.motion = motion

    def clip(self, stimulus: Stimulus) -> Clip:
        return Clip(self.motion, np.zeros((self.motion.n_frames, 2)))


def _cut_in_half(render):
    def rendering(*args, **kwargs) -> Path:
        path = render(*args, **kwargs)
        data = path.read_bytes()
        path.write_bytes(data[:len(data) // 2])  # as a full disk or a killed copy leaves it
        return path
    return rendering


@pytest.fixture
def stimulus(db) -> Stimulus:
    study = Study.objects.create(owner=User.objects.create_user("researcher"), title="Gait", video_width=SIZE[0],
                                 video_height=SIZE[1])
    system = System.objects.create(study=study, name="NAT", role=System.Role.NATURAL, kind="natural")
    control = ControlSignal.objects.create(study=study, name="walk", origin="held-out", control={}, seconds=2.0)
    return Stimulus.objects.create(study=study, system=system, control=control, content_key="k", task_id="task-1",
                                   status=Stimulus.Status.QUEUED)


def test_a_rendered_clip_cut_short_fails_its_task_with_the_reason_and_leaves_no_video(stimulus, walk, media,
                                                                                     monkeypatch):
    monkeypatch.setattr(clips, "source_of", lambda system: OneWalk(walk))
    monkeypatch.setattr(clips, "render_video", _cut_in_half(clips.render_video))

    outcome = generate_stimulus.apply((stimulus.pk,), task_id="task-1").get()

    stimulus.refresh_from_db()
    assert outcome["status"] == "failed" and stimulus.status == Stimulus.Status.FAILED
    assert stimulus.error.startswith(f"VideoError: {stimulus.video_path()}: cut short: the file declares 2 s")
    assert not stimulus.video_path().exists()


def test_a_rendered_clip_that_decodes_whole_is_done_with_its_length(stimulus, walk, media, monkeypatch):
    monkeypatch.setattr(clips, "source_of", lambda system: OneWalk(walk))

    assert generate_stimulus.apply((stimulus.pk,), task_id="task-1").get()["status"] == "done"

    stimulus.refresh_from_db()
    assert (stimulus.status, stimulus.duration_s) == (Stimulus.Status.DONE, 2.0) and stimulus.video_path().is_file()
