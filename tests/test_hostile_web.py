"""Hostile requests to the study app: each gets a clear 4xx (never a 500 or a debug page),
stores nothing, and files reach only whoever may see them.

- media: NUL bytes, hidden and unknown folders, Range numbers thousands of digits long;
- access: analysis reports for their owner only, the gallery for researchers, the health
  details behind login, the admin's writes scoped to the researcher's own studies;
- forms: cameras with NaN or Infinity, control files of infinite length or speed;
- uploads: a body over the limit refused from its declared length, before it is read;
- exports: spreadsheet formulas in the ratings CSV neutralised.
"""

from __future__ import annotations

import html
import io
import json
from pathlib import Path

import pytest
from django.contrib.auth.models import Permission, User
from django.core.files.uploadedfile import SimpleUploadedFile

from analysis.ratings.simulate import simulate_ratings
from generation.motion.dataset_options import DatasetOptions
from generation.render.camera import Camera
from studyapp.models import Assignment, ControlSignal, Participant, Rating, Stimulus, Study, System, camera_problem
from tests.study_fixtures import make_study

CLIP = bytes(range(256)) * 4


@pytest.fixture
def media_root(tmp_path: Path, settings) -> Path:
    root = tmp_path / "media"
    for folder in ("stimuli", "gallery", "private"):
        (root / folder).mkdir(parents=True)
        (root / folder / "clip.mp4").write_bytes(CLIP)
    (root / "stimuli" / ".clip.mp4.1234.part").write_bytes(CLIP)
    settings.MEDIA_ROOT = root
    return root


@pytest.fixture
def researcher(client, db) -> User:
    user = User.objects.create_user("researcher", password="pw-for-tests")
    client.force_login(user)
    return user


HOSTILE_MEDIA_PATHS = ["/media/%00/clip.mp4", "/media/stimuli/clip%00.mp4", "/media/stimuli/%00",
                       "/media/stimuli/.clip.mp4.1234.part", "/media/stimuli/..%2f..%2fprivate/clip.mp4",
                       "/media/private/clip.mp4", "/media/clip.mp4", "/media/reports/not-a-digest/ratings.csv",
                       "/media/reports/" + "0" * 64 + "/ratings.csv"]


@pytest.mark.django_db
@pytest.mark.parametrize("url", HOSTILE_MEDIA_PATHS)
def test_hostile_media_paths_are_404_with_the_studys_page(url, client, media_root, researcher):
    response = client.get(url)
    assert response.status_code == 404
    assert "Not found" in response.content.decode() and "Traceback" not in response.content.decode()


HUGE = "9" * 5000  # past int()'s 4,300-digit limit


@pytest.mark.django_db
@pytest.mark.parametrize("header, status, content_range", [
    (f"bytes={HUGE}-", 416, "bytes */1024"),
    (f"bytes={HUGE}-{HUGE}", 416, "bytes */1024"),
    (f"bytes=0-{HUGE}", 206, "bytes 0-1023/1024"),
    (f"bytes=-{HUGE}", 206, "bytes 0-1023/1024"),
    (f"bytes=10-{'0' * 5000}5", 200, None),  # last before first: not understood, the whole file
])
def test_range_numbers_thousands_of_digits_long_get_a_clear_answer(header, status, content_range, client, media_root):
    response = client.get("/media/stimuli/clip.mp4", HTTP_RANGE=header)
    assert response.status_code == status
    assert response.get("Content-Range") == content_range


@pytest.mark.django_db
def test_gallery_files_need_a_login(client, media_root):
    anonymous = client.get("/media/gallery/clip.mp4")
    assert anonymous.status_code == 302 and "/login/" in anonymous["Location"]
    assert client.get("/media/stimuli/clip.mp4").status_code == 200  # participants need no login
    client.force_login(User.objects.create_user("someone"))
    assert b"".join(client.get("/media/gallery/clip.mp4").streaming_content) == CLIP


def _upload(client, data: bytes):
    file = io.BytesIO(data)
    file.name = "ratings.csv"
    return client.post("/analysis/", {"ratings": file, "reference": "NAT"})


@pytest.mark.django_db
def test_a_report_and_its_files_are_served_to_its_owner_only(client, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path
    owner, other = User.objects.create_user("owner"), User.objects.create_user("other")
    client.force_login(owner)
    ratings = simulate_ratings({"NAT": 4.2, "MoGlow": 3.6}, 400, seed=2).to_csv(index=False).encode()
    page_url = _upload(client, ratings)["Location"]
    digest = page_url.rstrip("/").rsplit("/", 1)[1]
    files = [f"/media/reports/{digest}/{name}" for name in
             ("ratings.csv", "figures/means_ci.svg", "tables/system_means.csv")]
    assert client.get(page_url).status_code == 200
    assert all(client.get(url).status_code == 200 for url in files)

    client.force_login(other)
    assert client.get(page_url).status_code == 404
    assert all(client.get(url).status_code == 404 for url in files)
    # The same table uploaded by the other researcher is a report of their own.
    assert _upload(client, ratings)["Location"] != page_url

    client.logout()
    assert all(client.get(url).status_code == 302 for url in [page_url, *files])


@pytest.mark.django_db
def test_health_json_tells_the_public_only_ok_or_not(client):
    public = client.get("/health.json")
    assert public.status_code in (200, 503)
    assert json.loads(public.content) in ({"status": "ok"}, {"status": "degraded"})

    client.force_login(User.objects.create_user("someone"))
    details = json.loads(client.get("/health.json").content)
    assert {"database", "broker", "workers"} <= set(details)


@pytest.mark.django_db
def test_the_admin_makes_a_staff_researchers_new_study_their_own_and_lists_no_other_user(client):
    staff = User.objects.create_user("staff-researcher", password="pw", is_staff=True)
    staff.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    victim = User.objects.create_user("another-researcher")
    client.force_login(staff)

    form = client.get("/admin/studyapp/study/add/").content.decode()
    assert "another-researcher" not in form and 'name="owner"' not in form
    fields = {"title": "Mine", "question": "How natural?", "scale_min": 1, "scale_max": 5, "label_min": "no",
              "label_max": "yes", "instructions": "Watch.", "consent_text": "OK?", "clips_per_participant": 12,
              "ratings_per_stimulus": 5, "training_clips": 2, "bad_checks": 1, "natural_checks": 1,
              "bad_threshold": 4, "natural_threshold": 2, "reservation_minutes": 60, "platform": "link",
              "camera": '{"azimuth": 30}', "video_width": 320, "video_height": 240, "owner": victim.pk,
              "design": "single", "pages_per_participant": 0, "preference_strengths": 0, "instructed_checks": 0,
              "stop_after_failed_checks": 0, "min_screen_width": 0, "min_screen_height": 0, "path_tolerance_cm": 100}
    response = client.post("/admin/studyapp/study/add/", fields)

    assert response.status_code == 302, response.context["adminform"].form.errors
    assert Study.objects.get(title="Mine").owner == staff  # the posted owner is ignored
    assert not victim.studies.exists()


HOSTILE_CAMERAS = {
    "NaN": ('{"azimuth": NaN}', "&#x27;azimuth&#x27; must be a finite number"),
    "Infinity": ('{"distance": Infinity}', "&#x27;distance&#x27; must be a finite number"),
    "-Infinity": ('{"elevation": -Infinity}', "&#x27;elevation&#x27; must be a finite number"),
    "1e400": ('{"fov": 1e400}', "&#x27;fov&#x27; must be a finite number"),
    "text": ('{"azimuth": "north"}', "&#x27;azimuth&#x27; must be a number"),
    "a list": ("[1, 2]", "expected a JSON object of camera fields, got list"),
    "unknown field": ('{"zoom": 2}', "unknown Camera fields: zoom"),
}


@pytest.mark.parametrize("camera, message", HOSTILE_CAMERAS.values(), ids=HOSTILE_CAMERAS.keys())
def test_a_hostile_camera_description_is_named_by_the_study_check(camera, message):
    """The admin (and any code) stores the camera as JSON; Study.clean refuses these."""
    problem = camera_problem(json.loads(camera))
    assert problem and html.unescape(message) in f"not a camera description: {problem}"


HOSTILE_CAMERA_FIELDS = {"NaN": ("camera_azimuth", "NaN"), "Infinity": ("camera_distance", "Infinity"),
                         "-Infinity": ("camera_elevation", "-Infinity"), "1e400": ("camera_fov", "1e400"),
                         "text": ("camera_azimuth", "north")}


@pytest.mark.django_db
@pytest.mark.parametrize("field, value", HOSTILE_CAMERA_FIELDS.values(), ids=HOSTILE_CAMERA_FIELDS.keys())
def test_a_hostile_camera_field_is_a_400_naming_the_field(field, value, client, researcher):
    fields = {"title": "Gait", "question": "How natural?", "scale_min": 1, "scale_max": 5, "label_min": "bad",
              "label_max": "good", "instructions": "Watch.", "consent_text": "OK?", "clips_per_participant": 12,
              "ratings_per_stimulus": 5, "training_clips": 2, "bad_checks": 1, "natural_checks": 1,
              "bad_threshold": 4, "natural_threshold": 2, "reservation_minutes": 60, "platform": "link",
              "redirect_url": "", "video_width": 320, "video_height": 240, "design": "single",
              "pages_per_participant": 0, "preference_strengths": 0, "instructed_checks": 0,
              "stop_after_failed_checks": 0,
              **{f"camera_{name}": v for name, v in Camera().to_dict().items() if v is not None}, field: value}
    response = client.post("/studies/new/", fields)
    assert response.status_code == 400
    page = response.content.decode()
    assert "Enter a number." in page and f'name="{field}"' in page
    assert not Study.objects.exists()


HOSTILE_CONTROL_FILES = {
    "seconds Infinity (JSON)": ("path.json", b'{"segments": [{"type": "straight", "seconds": Infinity}]}',
                                "path.json: not JSON a study holds (Infinity is no number JSON has)"),
    "seconds .inf (YAML)": ("path.yaml", b"segments:\n  - type: straight\n    seconds: .inf\n",
                            "path.yaml: not YAML a study holds (the number inf is not finite)"),
    "seconds 1e12": ("path.json", b'{"segments": [{"type": "straight", "seconds": 1e12}]}',
                     "&#x27;seconds&#x27; must be a finite number within ±600"),
    "speed 1e308": ("path.json", b'{"segments": [{"type": "straight", "seconds": 2, "speed": 1e308}]}',
                    "&#x27;speed&#x27; must be a finite number within ±2000"),
    "turn rate NaN": ("path.json", b'{"segments": [{"type": "curve", "seconds": 2, "turn_rate": NaN}]}',
                      "path.json: not JSON a study holds (NaN is no number JSON has)"),
    "hours in many segments": ("path.json", json.dumps({"segments": [{"type": "stand", "seconds": 500}] * 3}).encode(),
                               "segment 1: the path&#x27;s segments last over 600 s in all"),
    "a segment that is no object": ("path.json", b'{"segments": [5]}', "segment 0 must be an object"),
    "not UTF-8": ("path.json", b'{"name": "\xe9t\xe9"}', "path.json: not UTF-8 text"),
    "100,000 nested brackets (JSON)": ("path.json", b"[" * 100_000 + b"]" * 100_000,
                                       "path.json: nested more than 20 levels deep"),
    "100,000 nested brackets (YAML)": ("path.yaml", b"segments: " + b"[" * 100_000,
                                       "path.yaml: nested too deeply to read"),
}


@pytest.mark.django_db
@pytest.mark.parametrize("name, content, message", HOSTILE_CONTROL_FILES.values(), ids=HOSTILE_CONTROL_FILES.keys())
def test_a_hostile_control_file_is_a_400_naming_the_field_and_adds_nothing(name, content, message, client,
                                                                           researcher):
    study = Study.objects.create(owner=researcher, title="Gait", video_width=160, video_height=120)
    # A checkpoint system as far as the controls need one: the data options it was trained on.
    System.objects.create(study=study, name="MoGlow", checkpoint="model.safetensors", kind="moglow",
                          metadata={"dataset_options": DatasetOptions().to_dict()})
    response = client.post(f"/studies/{study.pk}/controls/",
                           {"action": "file", "description": SimpleUploadedFile(name, content)})
    assert response.status_code == 400
    page = response.content.decode()
    assert message in page and "Traceback" not in page
    assert not ControlSignal.objects.exists()


class UnreadBody(io.RawIOBase):
    """A request body that counts what the server reads of it."""

    def __init__(self) -> None:
        self.bytes_read = 0

    def read(self, size: int = -1) -> bytes:
        chunk = b"x" * (64 * 1024 if size is None or size < 0 else min(size, 64 * 1024))
        self.bytes_read += len(chunk)
        return chunk

    def readline(self, size: int = -1) -> bytes:
        return self.read(size)


@pytest.mark.django_db
@pytest.mark.parametrize("url, declared", [("/studies/1/systems/", str(600_000_000)), ("/analysis/", str(60_000_000)),
                                           ("/p/some-study/rate/", str(600_000_000)),
                                           ("/analysis/", "9" * 5000)])
def test_an_upload_over_the_limit_is_refused_before_its_body_is_read(url, declared, client, researcher):
    body = UnreadBody()
    response = client.generic("POST", url, b"", content_type="multipart/form-data; boundary=x",
                              CONTENT_LENGTH=declared, **{"wsgi.input": body})
    assert response.status_code == 413
    page = response.content.decode()
    assert "Upload too large" in page and "this page takes at most" in page
    assert body.bytes_read == 0


@pytest.mark.django_db
def test_the_ratings_export_neutralises_spreadsheet_formulas(client, researcher):
    study = make_study(controls=1)
    study.owner = researcher
    study.save()
    system = study.systems.get(name="MoGlow")
    system.name = "=HYPERLINK(\"http://evil.example\",\"x\")"
    system.save()
    participant = Participant.objects.create(study=study, platform_id="p1")
    stimulus = Stimulus.objects.get(system=system)
    assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=0)
    Rating.objects.create(assignment=assignment, value=4)

    export = client.get(f"/studies/{study.pk}/ratings.csv").content.decode()
    assert "'=HYPERLINK" in export and ",=HYPERLINK" not in export


@pytest.mark.django_db
@pytest.mark.parametrize("command", [["export_controls", "9999", "--out", "{tmp}/bundle"],
                                     ["add_system", "9999", "Lab-B", "--motion", "{tmp}"],
                                     ["generate_stimuli", "9999"]])
def test_study_commands_refuse_bad_input_with_exit_status_2(command, tmp_path):
    from django.core.management import CommandError, call_command

    with pytest.raises(CommandError, match="no study with id 9999") as refused:
        call_command(*[word.format(tmp=tmp_path) for word in command])
    assert refused.value.returncode == 2


@pytest.mark.django_db
def test_a_checkpoint_of_a_kind_the_registry_does_not_know_is_named_on_the_controls_page(client, researcher):
    study = Study.objects.create(owner=researcher, title="Gait", video_width=160, video_height=120)
    System.objects.create(study=study, name="Old model", checkpoint="model.safetensors", kind="uninstalled-kind",
                          metadata={"dataset_options": DatasetOptions().to_dict()})
    page = client.get(f"/studies/{study.pk}/controls/").content.decode()
    assert "Old model is a &#x27;uninstalled-kind&#x27; model, a kind this server does not know" in page
