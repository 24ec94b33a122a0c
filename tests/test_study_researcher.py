"""The researcher's side of a study: pages behind login, uploads, controls and generation.

Checkpoints are tiny MoGlows trained for seconds on real clips; videos are rendered from
real motion capture. The task queue is a filesystem broker in a temporary folder (what
is queued can be counted there), or a Redis address where nothing listens.
"""

from __future__ import annotations

import io
import json
import pickle
import struct
import subprocess
import time
from datetime import timedelta
from pathlib import Path
from types import SimpleNamespace

import imageio_ffmpeg
import pytest
import torch
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from django.test import Client
from django.utils import timezone
from safetensors.torch import load_file, save_file

from generation import registry
from generation.checkpoints.checkpoint import FORMAT_KEY, load_checkpoint, read_meta
from generation.checkpoints.store import tensor_digest
from generation.render.camera import Camera
from studyapp.models import ControlSignal, Participant, Stimulus, Study, System
from studyapp.server.celery import app as celery_app
from studyapp.server.embedded import FILESYSTEM_BROKER_URL, filesystem_broker_options
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.controls import control_kind
from studyapp.stimuli.dispatch import STALE_TASK_MINUTES, queue_stimuli
from studyapp.tasks import generate_stimulus
from tests.study_setup import CLIPS, link_clips, study_files


@pytest.fixture(scope="module")
def files(motion_data, tmp_path_factory) -> SimpleNamespace:
    return study_files(motion_data, tmp_path_factory.getbasetemp())


@pytest.fixture
def site(settings, tmp_path, files) -> Path:
    settings.MEDIA_ROOT = tmp_path / "media"
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    settings.VAR_DIR = tmp_path / "var"  # sampled motion of this test only
    settings.VAR_DIR.mkdir(exist_ok=True)
    (settings.VAR_DIR / "cache").symlink_to(files.root / "var" / "cache")  # the checkpoints' training data
    settings.MOTION_DATA = files.clips
    return tmp_path


@pytest.fixture
def queue(tmp_path) -> Path:
    """A private filesystem broker; yields the folder each queued message lands in."""
    saved = celery_app.conf.broker_url, celery_app.conf.broker_transport_options
    options = filesystem_broker_options(tmp_path / "var")
    celery_app.conf.broker_url, celery_app.conf.broker_transport_options = FILESYSTEM_BROKER_URL, options
    yield Path(options["data_folder_out"])
    celery_app.conf.broker_url, celery_app.conf.broker_transport_options = saved


@pytest.fixture
def broker_down():
    saved = celery_app.conf.broker_url, celery_app.conf.broker_transport
    celery_app.conf.broker_url = "redis://127.0.0.1:9/0"  # the discard port: nothing answers
    celery_app.conf.broker_transport = None  # the URL's scheme says which
    yield
    celery_app.conf.broker_url, celery_app.conf.broker_transport = saved


@pytest.fixture
def researcher(client) -> User:
    user = User.objects.create_user("researcher", password="pw-for-tests")
    client.force_login(user)
    return user


def new_study(owner: User, **fields) -> Study:
    return Study.objects.create(owner=owner, title="Locomotion", video_width=160, video_height=120, **fields)


def upload_checkpoint(client, study: Study, data: bytes, filename: str = "model.safetensors", name: str = "MoGlow",
                      role: str = "model"):
    return client.post(f"/studies/{study.pk}/systems/", {
        "action": "checkpoint", "name": name, "role": role, "temperature": "1.0",
        "checkpoint": SimpleUploadedFile(filename, data)})


def first_frame(video: Path) -> bytes:
    frames = imageio_ffmpeg.read_frames(str(video))
    next(frames)  # the stream's description
    try:
        return bytes(next(frames))
    finally:
        frames.close()


def stored_files(folder: Path) -> list[str]:
    """Every file under ``folder`` (hidden ones too), relative to it."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


# --- login and ownership ---------------------------------------------------------

PAGES = ["/studies/", "/studies/new/", "/studies/{pk}/", "/studies/{pk}/systems/", "/studies/{pk}/controls/",
         "/studies/{pk}/stimuli/", "/studies/{pk}/stimuli/progress.json", "/studies/{pk}/monitor/",
         "/studies/{pk}/ratings.csv"]


@pytest.mark.django_db
def test_researcher_pages_need_a_login(client):
    study = new_study(User.objects.create_user("owner"))
    for page in PAGES:
        response = client.get(page.format(pk=study.pk))
        assert response.status_code == 302 and response["Location"].startswith("/login/"), page
    for action in ("open/", "report/", "stimuli/1/retry/"):
        assert client.post(f"/studies/{study.pk}/{action}")["Location"].startswith("/login/")


@pytest.mark.django_db
def test_a_researcher_who_is_not_staff_logs_in_on_the_login_page(client):
    User.objects.create_user("plain", password="pw-for-tests")
    form = client.get("/login/?next=/studies/")
    assert form.status_code == 200 and "csrfmiddlewaretoken" in form.content.decode()
    wrong = client.post("/login/", {"username": "plain", "password": "wrong", "next": "/studies/"})
    assert wrong.status_code == 200 and "do not match" in wrong.content.decode()
    response = client.post("/login/", {"username": "plain", "password": "pw-for-tests", "next": "/studies/"})
    assert response.status_code == 302 and response["Location"] == "/studies/"
    assert client.get("/studies/").status_code == 200


@pytest.mark.django_db
def test_the_admin_shows_a_researcher_only_their_own_studies(client):
    from django.contrib.auth.models import Permission

    staff = User.objects.create_user("staff-researcher", password="pw", is_staff=True)
    staff.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    client.force_login(staff)
    mine, theirs = new_study(staff), new_study(User.objects.create_user("someone-else"))
    theirs.title = "Their secret study"
    theirs.save()
    for model in ("study", "system", "participant", "rating"):
        assert client.get(f"/admin/studyapp/{model}/").status_code == 200, model
    listing = client.get("/admin/studyapp/study/").content.decode()
    assert f"/admin/studyapp/study/{mine.pk}/change/" in listing and "Their secret study" not in listing
    assert client.get(f"/admin/studyapp/study/{theirs.pk}/change/").status_code == 302  # "does not exist"
    form = client.get("/admin/studyapp/system/add/").content.decode()
    assert f'value="{mine.pk}"' in form and f'value="{theirs.pk}"' not in form


@pytest.mark.django_db
def test_a_researcher_sees_only_their_own_studies(client, researcher):
    mine = new_study(researcher)
    theirs = new_study(User.objects.create_user("someone-else"), is_open=True)
    theirs.title = "Their secret study"
    theirs.save()
    listing = client.get("/studies/").content.decode()
    assert f"/studies/{mine.pk}/" in listing and "Their secret study" not in listing
    for page in PAGES[2:]:
        assert client.get(page.format(pk=theirs.pk)).status_code == 404, page
        assert client.get(page.format(pk=mine.pk)).status_code == 200, page
    for action in ("open/", "report/"):
        assert client.post(f"/studies/{theirs.pk}/{action}", {"open": "0"}).status_code == 404
    theirs.refresh_from_db()
    assert theirs.is_open


@pytest.mark.django_db
def test_the_study_form_checks_the_study_and_needs_csrf(client, researcher):
    fields = {"title": "Gait", "question": "How natural?", "scale_min": 1, "scale_max": 10, "label_min": "bad",
              "label_max": "good", "instructions": "Watch.", "consent_text": "OK?", "clips_per_participant": 12,
              "ratings_per_stimulus": 5, "training_clips": 2, "bad_checks": 1, "natural_checks": 1,
              "bad_threshold": 4, "natural_threshold": 2, "discard_early": "on", "reservation_minutes": 60,
              "platform": "prolific", "completion_code": "XYZ", "redirect_url": "",
              **{f"camera_{name}": value for name, value in {**Camera().to_dict(), "azimuth": 20}.items()
                 if value is not None},
              "video_width": 320, "video_height": 240, "design": "single", "pages_per_participant": 8,
              "preference_strengths": 0, "instructed_checks": 0, "stop_after_failed_checks": 0}
    refused = client.post("/studies/new/", {**fields, "scale_min": 10, "scale_max": 1})
    assert refused.status_code == 400 and "the scale must rise" in refused.content.decode()
    assert client.post("/studies/new/", {**fields, "video_width": 321}).status_code == 400
    assert not Study.objects.exists()

    saved = client.post("/studies/new/", fields)
    study = Study.objects.get()
    assert saved.status_code == 302 and saved["Location"] == f"/studies/{study.pk}/systems/"
    camera = {**Camera().to_dict(), "azimuth": 20.0}
    assert (study.owner, study.scale_max, study.camera, study.platform) == (researcher, 10, camera, "prolific")

    strict = Client(enforce_csrf_checks=True)
    strict.force_login(researcher)
    assert strict.post("/studies/new/", fields).status_code == 403
    assert strict.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"}).status_code == 403
    assert Study.objects.count() == 1 and not System.objects.exists()

    # Once a participant has started, the instrument is fixed; the rest can still change.
    Participant.objects.create(study=study, platform_id="p1")
    edited = client.post(f"/studies/{study.pk}/", {**fields, "scale_max": 5, "camera_azimuth": 90,
                                                   "question": "Other?", "ratings_per_stimulus": 8})
    study.refresh_from_db()
    assert edited.status_code == 302
    assert (study.scale_max, study.camera, study.question, study.ratings_per_stimulus) == (10, camera,
                                                                                            "How natural?", 8)


# --- systems ---------------------------------------------------------------------

@pytest.mark.django_db
def test_an_uploaded_checkpoint_is_validated_stored_by_digest_and_described(client, researcher, site, files):
    study = new_study(researcher)
    response = upload_checkpoint(client, study, files.good.read_bytes(), "moglow-tiny.safetensors")
    assert response.status_code == 302
    system = System.objects.get()
    model, meta = load_checkpoint(files.good)
    assert (system.role, system.kind, system.temperature) == ("model", "moglow", 1.0)
    assert system.metadata["step"] == 20 and system.metadata["preset"] == "custom"
    assert system.metadata["parameters"] == sum(p.numel() for p in model.parameters())
    assert system.metadata["data_fingerprint"] == meta.data_fingerprint
    assert system.metadata["file"] == "moglow-tiny.safetensors"
    assert stored_files(site / "checkpoints") == [f"{system.checkpoint_digest}.safetensors"]
    assert system.checkpoint_path().read_bytes() == files.good.read_bytes()
    page = client.get(f"/studies/{study.pk}/systems/").content.decode()
    assert "MoGlow" in page and meta.data_fingerprint[:12] in page
    # The same file as a second model system is refused; as a BAD system it is another condition.
    again = upload_checkpoint(client, study, files.good.read_bytes(), name="Copy")
    assert again.status_code == 400 and "already system" in again.content.decode()
    assert upload_checkpoint(client, study, files.early.read_bytes(), name="Early", role="bad").status_code == 302
    assert System.objects.filter(role="bad").get().metadata["step"] == 2


def resaved(checkpoint: Path, change) -> bytes:
    """The checkpoint with its tensors changed by ``change`` and a digest that matches them."""
    tensors = load_file(str(checkpoint))
    change(tensors)
    header = {FORMAT_KEY: read_meta(checkpoint).to_json(), "digest": tensor_digest(tensors)}
    buffer = checkpoint.parent / "resaved.safetensors"
    save_file(tensors, str(buffer), metadata=header)
    data = buffer.read_bytes()
    buffer.unlink()
    return data


def with_header(checkpoint: Path, change) -> bytes:
    """The checkpoint with its JSON description replaced by ``change(description)``."""
    tensors = load_file(str(checkpoint))
    description = json.loads(read_meta(checkpoint).to_json())
    header = {FORMAT_KEY: json.dumps(change(description)), "digest": tensor_digest(tensors)}
    buffer = checkpoint.parent / "reheaded.safetensors"
    save_file(tensors, str(buffer), metadata=header)
    data = buffer.read_bytes()
    buffer.unlink()
    return data


def tampered(data: bytes) -> bytes:
    """One byte of tensor data flipped, the header left as it was."""
    (length,) = struct.unpack("<Q", data[:8])
    position = 8 + length + 40
    return data[:position] + bytes([data[position] ^ 0xFF]) + data[position + 1:]


BAD_UPLOADS = {
    "pickle renamed": (lambda f: pickle.dumps({"weights": [1.0, 2.0]}), "model.safetensors",
                       "not a readable safetensors file"),
    "torch.save renamed": (lambda f: _torch_saved(), "model.safetensors", "not a readable safetensors file"),
    "tampered": (lambda f: tampered(f.good.read_bytes()), "model.safetensors", "the tensors do not match"),
    "missing tensor": (lambda f: resaved(f.good, lambda t: t.pop(sorted(t)[0])), "model.safetensors",
                       "missing tensor"),
    "wrong shape": (lambda f: resaved(f.good, lambda t: t.update({sorted(t)[0]: torch.zeros(3, 1)})),
                    "model.safetensors", "has shape (3, 1)"),
    "wrong extension": (lambda f: f.good.read_bytes(), "model.pt", "must be a .safetensors file"),
    "header a list": (lambda f: with_header(f.good, lambda d: [d]), "model.safetensors", "is not an object"),
    "dimension a string": (lambda f: with_header(f.good, lambda d: {**d, "pose_dim": "63"}), "model.safetensors",
                           "pose_dim must be an integer"),
    "negative dimension": (lambda f: with_header(f.good, lambda d: {**d, "pose_dim": -5}), "model.safetensors",
                           "pose_dim must be positive"),
    "hyperparameters that build no model": (
        lambda f: with_header(f.good, lambda d: {**d, "hyperparameters": {**d["hyperparameters"], "lstm_hidden": -1}}),
        "model.safetensors", "do not build a"),
}


def _torch_saved() -> bytes:
    buffer = io.BytesIO()
    torch.save({"weight": torch.ones(2)}, buffer)
    return buffer.getvalue()


@pytest.mark.django_db
@pytest.mark.parametrize("case", BAD_UPLOADS)
def test_a_bad_checkpoint_upload_is_a_form_error_and_leaves_nothing(client, researcher, site, files, case):
    make, filename, message = BAD_UPLOADS[case]
    study = new_study(researcher)
    response = upload_checkpoint(client, study, make(files), filename)
    assert response.status_code == 400
    assert message in response.content.decode()
    assert not System.objects.exists()
    assert stored_files(site / "checkpoints") == []


@pytest.mark.django_db
def test_an_oversized_checkpoint_is_refused(client, researcher, site, files, settings):
    settings.MAX_CHECKPOINT_UPLOAD_BYTES = 1000
    response = upload_checkpoint(client, new_study(researcher), files.good.read_bytes())
    assert response.status_code == 400 and "over the 0 MB limit" in response.content.decode()
    assert not System.objects.exists() and stored_files(site / "checkpoints") == []


@pytest.mark.django_db
def test_bad_videos_become_finished_stimuli_and_a_fake_video_is_refused(client, researcher, site, files):
    study = new_study(researcher)
    fake = client.post(f"/studies/{study.pk}/systems/", {"action": "videos", "name": "BAD", "videos": [
        SimpleUploadedFile("good.mp4", files.video.read_bytes()),
        SimpleUploadedFile("fake.mp4", b"\x00\x00\x00\x18ftypisom" + b"not really a video" * 50)]})
    assert fake.status_code == 400 and "fake.mp4: its video does not decode" in fake.content.decode()
    text = client.post(f"/studies/{study.pk}/systems/", {"action": "videos", "name": "BAD", "videos": [
        SimpleUploadedFile("notes.mp4", b"just some text, not a video at all")]})
    assert text.status_code == 400 and "no ftyp box" in text.content.decode()
    assert not System.objects.exists() and stored_files(site / "media") == []

    titled = site / "titled.mp4"  # a video whose container names the model it came from
    subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(files.video), "-c", "copy",
                    "-metadata", "title=MoGlow-early-checkpoint", str(titled)], check=True)
    assert b"MoGlow-early-checkpoint" in titled.read_bytes()
    response = client.post(f"/studies/{study.pk}/systems/", {"action": "videos", "name": "BAD", "videos": [
        SimpleUploadedFile("good.mp4", titled.read_bytes())]})
    titled.unlink()
    assert response.status_code == 302
    stimulus = Stimulus.objects.get()
    assert (stimulus.system.role, stimulus.status, stimulus.control) == ("bad", "done", None)
    assert stimulus.duration_s == pytest.approx(1.0, abs=0.06)
    assert b"MoGlow-early-checkpoint" not in stimulus.video_path().read_bytes()  # served without its metadata
    assert first_frame(stimulus.video_path()) == first_frame(files.video)  # the same pictures
    assert stored_files(site / "media") == [f"stimuli/{stimulus.token}.mp4"]
    assert "Last-Modified" not in client.get(stimulus.video_url).headers  # render times would group systems


# --- controls --------------------------------------------------------------------

@pytest.mark.django_db
def test_controls_come_from_held_out_clips_presets_and_files(client, researcher, site, files):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())

    page = client.get(f"/studies/{study.pk}/controls/").content.decode()
    assert page.count("Add presets") == 1 and page.count("Add from file") == 1 and "Add label controls" not in page
    assert client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""}).status_code == 302
    held = list(study.controls.filter(origin="held-out").order_by("name"))
    # One walking and one running take are held out of the five clips.
    assert [c.source_clip for c in held] == ["data/dataset-1_run_happy_001.bvh", "data/dataset-1_walk_old_002.bvh"]
    for control in held:
        assert (files.clips / control.source_clip).is_file()
        assert control.seconds == 2.0 and len(control.control["velocities"]) == 40 and control.control["fps"] == 20.0
    assert client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle", "stand-still"]}).status_code == 302
    yaml_file = SimpleUploadedFile("paths.yaml", b"- segments: [{type: straight, speed: 100, seconds: 1}]\n"
                                                 b"- segments: [{type: sidestep, direction: left, seconds: 1}]\n")
    assert client.post(f"/studies/{study.pk}/controls/", {"action": "file", "description": yaml_file}).status_code == 302
    names = set(study.controls.values_list("name", flat=True))
    assert {"walk-circle", "stand-still", "paths-0", "paths-1"} <= names and len(names) == 6

    broken = SimpleUploadedFile("broken.yaml", b"- segments: [{type: teleport, seconds: 1}]\n")
    response = client.post(f"/studies/{study.pk}/controls/", {"action": "file", "description": broken})
    assert response.status_code == 400 and "broken.yaml: path 0: segment 0: unknown segment type" in response.content.decode()
    # Adding the same controls again changes nothing.
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""})
    assert study.controls.count() == 6


@pytest.mark.django_db
def test_held_out_controls_refuse_data_the_models_were_not_trained_on(client, researcher, site, files, settings, motion_data, tmp_path):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    settings.MOTION_DATA = link_clips(motion_data, tmp_path / "other")
    (settings.MOTION_DATA / "data" / f"dataset-1_{CLIPS[-1]}.bvh").unlink()
    response = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2"})
    assert response.status_code == 400 and "is not the data the checkpoints were trained on" in response.content.decode()
    assert not ControlSignal.objects.exists()


@pytest.mark.django_db
def test_a_label_controlled_model_gets_label_controls_and_its_stimuli_render(client, researcher, site, files, queue,
                                                                            settings):
    settings.MOTION_DATA = files.labelled
    study = new_study(researcher)
    assert upload_checkpoint(client, study, files.erd.read_bytes(), name="ERD").status_code == 302
    erd = System.objects.get(name="ERD")
    assert control_kind(study) == registry.LABELS and "walk" in erd.metadata["labels"]["actions"]
    assert client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"}).status_code == 302
    page = client.get(f"/studies/{study.pk}/controls/").content.decode()
    assert page.count("Add label controls") == 1 and "Add presets" not in page

    assert client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""}).status_code == 302
    held = list(study.controls.filter(origin="held-out"))
    assert held and all(c.control["type"] == "attributes" and c.source_clip for c in held)
    assert {c.control["action"] for c in held} == {"walk", "run"} and all(c.control["fps"] == 30.0 for c in held)
    response = client.post(f"/studies/{study.pk}/controls/", {"action": "labels", "actions": ["walk"],
                                                              "styles": ["happy", "normal"], "seconds": "1"})
    assert response.status_code == 302
    assert sorted(study.controls.filter(origin="synthetic").values_list("name", flat=True)) == [
        "walk-happy-1s", "walk-normal-1s"]
    refused = client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle"]})
    assert refused.status_code == 400  # not a form of this study's page: nothing added
    assert study.controls.count() == len(held) + 2

    stimuli, _ = plan_stimuli(study)
    assert len(stimuli) == 2 * len(held) + 2  # ERD for every control, NAT for the held-out ones
    queue_stimuli(stimuli)
    for stimulus in (s for s in stimuli if s.system.name == "ERD"):
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
        stimulus.refresh_from_db()
        expected = stimulus.control.seconds
        assert stimulus.duration_s == pytest.approx(expected, abs=0.05) and stimulus.video_path().is_file()


@pytest.mark.django_db
def test_path_and_label_controlled_models_do_not_share_a_study(client, researcher, site, files):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    response = upload_checkpoint(client, study, files.erd.read_bytes(), name="ERD")
    assert response.status_code == 400
    assert response.context["refused"]["problems"] == [
        "model.safetensors: it follows action and style labels, and the study's checkpoints (MoGlow) follow a path: "
        "one study holds one kind of model"]
    assert list(study.systems.values_list("name", flat=True)) == ["MoGlow"]


# --- generation ------------------------------------------------------------------

def study_with_everything(client, researcher, files) -> Study:
    """MoGlow, an early checkpoint as BAD, NAT; two held-out and two synthetic controls."""
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    upload_checkpoint(client, study, files.early.read_bytes(), name="Early", role="bad")
    client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"})
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "1", "count": ""})
    client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle", "stand-still"]})
    assert (study.systems.count(), study.controls.count()) == (3, 4)
    return study


@pytest.mark.django_db
def test_generating_twice_makes_the_same_stimuli_and_queues_them_once(client, researcher, site, files, queue,
                                                                      settings):
    study = study_with_everything(client, researcher, files)
    first = client.post(f"/studies/{study.pk}/stimuli/", {"seed": "0"})
    assert first.status_code == 302
    rows = {s.pk: s.content_key for s in Stimulus.objects.all()}
    # MoGlow and BAD for each of 4 controls, NAT for the 2 held-out ones.
    assert len(rows) == 4 + 4 + 2 == len(set(rows.values()))
    assert Stimulus.objects.filter(system__role="natural", control__origin="synthetic").count() == 0
    assert set(Stimulus.objects.values_list("status", flat=True)) == {"queued"}
    assert len(list(queue.iterdir())) == 2 + 2  # one sampling message per model system, one render per NAT clip
    # Right after Generate no worker has had the time to take a clip: no false alarm.
    assert "no worker answers" not in client.get(f"/studies/{study.pk}/stimuli/").content.decode()
    # A heartbeat's time later, nothing touched and no worker answering the ping: now say so.
    Stimulus.objects.update(updated=timezone.now() - timedelta(seconds=settings.STUDY_LOST_AFTER_S + 1))
    assert "no worker answers" in client.get(f"/studies/{study.pk}/stimuli/").content.decode()

    second = client.post(f"/studies/{study.pk}/stimuli/", {"seed": "0"})
    assert second.status_code == 302
    assert {s.pk: s.content_key for s in Stimulus.objects.all()} == rows
    assert len(list(queue.iterdir())) == 4
    # A new seed is new content for the models, not for NAT.
    plan_stimuli(study, seed=1)
    assert Stimulus.objects.count() == 10 + 8


@pytest.mark.django_db
def test_a_stopped_broker_is_a_clear_message_and_nothing_is_queued(client, researcher, site, files, broker_down):
    study = study_with_everything(client, researcher, files)
    started = time.monotonic()
    response = client.post(f"/studies/{study.pk}/stimuli/", {"seed": "0"})
    assert time.monotonic() - started < 10  # a bounded wait, not Celery's retry loop
    assert response.status_code == 503
    assert "broker does not answer" in response.content.decode()
    assert Stimulus.objects.count() == 10
    assert set(Stimulus.objects.values_list("status", flat=True)) == {"pending"}
    assert set(Stimulus.objects.values_list("task_id", flat=True)) == {""}


def run_task(stimulus: Stimulus, task_id: str | None = None) -> dict:
    """Run the stimulus's generation task in this process, as a worker would run the message
    the row was last sent with (or the message ``task_id``)."""
    task_id = task_id or Stimulus.objects.get(pk=stimulus.pk).task_id
    return generate_stimulus.apply((stimulus.pk,), task_id=task_id).get()


@pytest.mark.django_db
def test_a_stimulus_sent_twice_is_rendered_once_and_a_stuck_one_is_sent_again(client, researcher, site, files, queue):
    study = study_with_everything(client, researcher, files)
    stimuli, _ = plan_stimuli(study)
    stimulus = stimuli[0]
    assert queue_stimuli([stimulus]) == 1
    first = Stimulus.objects.get(pk=stimulus.pk).task_id
    assert queue_stimuli([Stimulus.objects.get(pk=stimulus.pk)]) == 0  # queued and recent: not sent again
    assert queue_stimuli([stimulus]) == 0  # a stale copy of the row (a second click) sends nothing either
    Stimulus.objects.filter(pk=stimulus.pk).update(updated=timezone.now() - timedelta(minutes=STALE_TASK_MINUTES + 1))
    assert queue_stimuli([Stimulus.objects.get(pk=stimulus.pk)]) == 1  # stuck: sent again, with a new task id
    second = Stimulus.objects.get(pk=stimulus.pk).task_id
    assert second != first
    assert run_task(stimulus, task_id=first)["status"] == "nothing to do"  # the superseded message
    assert run_task(stimulus, task_id=second)["status"] == "done"
    assert Stimulus.objects.get(pk=stimulus.pk).attempts == 1


@pytest.mark.django_db
def test_a_task_renders_model_and_natural_clips_once_and_reports_a_failure(client, researcher, site, files, queue, settings):
    study = study_with_everything(client, researcher, files)
    client.post(f"/studies/{study.pk}/stimuli/", {"seed": "0"})
    model = Stimulus.objects.filter(system__name="MoGlow", control__origin="held-out").first()
    natural = Stimulus.objects.filter(system__role="natural").first()
    stale = model.video_path().parent / f".{model.token}.mp4.abc123.part"
    stale.parent.mkdir(parents=True, exist_ok=True)
    stale.write_bytes(b"half a video")
    assert client.get(f"/media/stimuli/{stale.name}").status_code == 404  # never served

    for stimulus in (model, natural):
        assert run_task(stimulus)["status"] == "done"
        stimulus.refresh_from_db()
        assert (stimulus.status, stimulus.attempts, stimulus.error) == ("done", 1, "")
        assert stimulus.duration_s == pytest.approx(1.0)
        assert client.get(stimulus.video_url).status_code == 200
    assert not stale.exists()
    assert run_task(model)["status"] == "nothing to do"
    model.refresh_from_db()
    assert model.attempts == 1

    broken = Stimulus.objects.filter(system__name="Early").first()
    broken.system.checkpoint_path().rename(site / "moved.safetensors")
    assert run_task(broken)["status"] == "failed"
    progress = client.get(f"/studies/{study.pk}/stimuli/progress.json").json()
    assert progress["counts"]["failed"] == 1 and progress["counts"]["done"] == 2
    assert progress["failed"][0]["system"] == "Early" and "checkpoint of Early is missing" in progress["failed"][0]["error"]
    page = client.get(f"/studies/{study.pk}/stimuli/").content.decode()
    assert "checkpoint of Early is missing" in page and f"/stimuli/{broken.pk}/retry/" in page

    (site / "moved.safetensors").rename(broken.system.checkpoint_path())
    assert client.post(f"/studies/{study.pk}/stimuli/{broken.pk}/retry/").status_code == 302
    broken.refresh_from_db()
    assert broken.status == "queued"
    assert run_task(broken)["status"] == "done"
    broken.refresh_from_db()
    assert (broken.status, broken.attempts) == ("done", 2)
