"""The study bundle on the researcher's pages: the download behind login and the owner
check, and the import page's upload with CSRF, its refusals answered 400 with the reason."""

from __future__ import annotations

import io
import json
import zipfile

import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from django.test import Client

from studyapp.models import Participant, Study
from studyapp.server.uploads.upload_limit import FORM_MARGIN_BYTES, request_limit
from tests.test_hostile_bundles import rewritten, small_study
from tests.test_study_researcher import files, researcher, site  # noqa: F401 (fixtures)

pytestmark = pytest.mark.django_db


def download(client: Client, study: Study, videos: bool = False):
    return client.get(f"/studies/{study.pk}/bundle.zip" + ("?videos=1" if videos else ""))


def test_the_bundle_is_downloaded_from_the_study_page_by_its_owner_only(client, researcher, site, files):
    study = small_study(researcher, files)
    assert f"/studies/{study.pk}/bundle.zip" in client.get(f"/studies/{study.pk}/").content.decode()
    response = download(client, study)
    assert response.status_code == 200 and response["Content-Disposition"].startswith("attachment")
    archive = zipfile.ZipFile(io.BytesIO(b"".join(response.streaming_content)))
    manifest = json.loads(archive.read("manifest.json"))
    assert set(manifest["files"]) == set(archive.namelist()) - {"manifest.json"}
    uploaded = study.stimuli.get(system__name="BAD")  # an uploaded video is its system's source: always there
    assert [name for name in archive.namelist() if name.startswith("stimuli/")] == [f"stimuli/{uploaded.token}.mp4"]
    with_videos = zipfile.ZipFile(io.BytesIO(b"".join(download(client, study, videos=True).streaming_content)))
    assert sum(name.startswith("stimuli/") for name in with_videos.namelist()) == study.stimuli.count() == 3

    client.force_login(User.objects.create_user("someone-else"))
    assert download(client, study).status_code == 404
    client.logout()
    assert download(client, study)["Location"].startswith("/login/")


def test_a_bundle_uploaded_on_the_import_page_becomes_a_closed_study_of_the_uploader(client, researcher, site, files,
                                                                                     tmp_path, settings):
    original = small_study(researcher, files)
    bundle = tmp_path / "study.zip"
    bundle.write_bytes(b"".join(download(client, original).streaming_content))
    importer = User.objects.create_user("importer")
    client.force_login(importer)
    assert client.get("/studies/import/").status_code == 200
    response = client.post("/studies/import/", {"bundle": SimpleUploadedFile("study.zip", bundle.read_bytes())})
    study = Study.objects.get(owner=importer)
    assert response.status_code == 302 and response["Location"] == f"/studies/{study.pk}/"
    assert (study.title, study.is_open, study.systems.count()) == (original.title, False, 3)
    assert "clip(s) to render" in client.get(response["Location"]).content.decode()


def test_the_import_page_needs_a_login_and_csrf_and_answers_a_refused_bundle_with_400(client, researcher, site, files,
                                                                                      tmp_path):
    bundle = tmp_path / "study.zip"
    bundle.write_bytes(b"".join(download(client, small_study(researcher, files)).streaming_content))
    studies = Study.objects.count()
    strict = Client(enforce_csrf_checks=True)
    strict.force_login(researcher)
    assert strict.post("/studies/import/", {"bundle": SimpleUploadedFile("study.zip", bundle.read_bytes())}
                       ).status_code == 403
    lying = rewritten(bundle, {"ratings.csv": b"participant\n"}, listed=False)
    refused = client.post("/studies/import/", {"bundle": SimpleUploadedFile("study.zip", lying.read_bytes())})
    assert refused.status_code == 400
    assert "ratings.csv: its SHA-256 or size differs from manifest.json" in refused.content.decode()
    not_zip = client.post("/studies/import/", {"bundle": SimpleUploadedFile("study.txt", b"hello")})
    assert not_zip.status_code == 400 and "a study bundle is a .zip file" in not_zip.content.decode()
    assert Study.objects.count() == studies and not Participant.objects.exists()
    anonymous = Client().post("/studies/import/", {"bundle": SimpleUploadedFile("study.zip", bundle.read_bytes())})
    assert anonymous.status_code == 302 and anonymous["Location"].startswith("/login/")
    assert Study.objects.count() == studies


def test_the_import_page_takes_a_bundle_as_large_as_the_bundle_limit(settings):
    assert request_limit("/studies/import/") == settings.MAX_BUNDLE_UPLOAD_BYTES + FORM_MARGIN_BYTES
    assert request_limit("/studies/new/") < request_limit("/studies/import/")


def test_platform_ids_leave_as_keyed_hashes_and_user_agents_not_at_all(client, researcher, site, files, tmp_path):
    import hashlib
    import hmac

    from django.core.management import call_command
    from django.core.management.base import CommandError

    study = small_study(researcher, files)
    Participant.objects.create(study=study, platform_id="PID-5f3a", user_agent="Mozilla/5.0 (X11; Linux) Firefox/133",
                               platform_data={"PROLIFIC_PID": "PID-5f3a", "SESSION_ID": "session-77"})
    key = tmp_path / "key.txt"
    key.write_text("a key the researcher keeps\n")

    def exported(name: str, *options: str) -> dict[str, bytes]:
        call_command("export_study", str(study.pk), "--out", str(tmp_path / name), *options, stdout=io.StringIO())
        with zipfile.ZipFile(tmp_path / name) as archive:
            return {member: archive.read(member) for member in archive.namelist()}

    keyed, keyed_again = (exported(name, "--pseudonym-key-file", str(key)) for name in ("a.zip", "b.zip"))
    unkeyed, unkeyed_again = exported("c.zip"), exported("d.zip")
    for bundle in (keyed, unkeyed):
        assert not any(b"PID-5f3a" in data or b"session-77" in data or b"Firefox" in data for data in bundle.values())
    participant = json.loads(keyed["participants.json"])["participants"][0]
    expected = hmac.new(b"a key the researcher keeps", b"PID-5f3a", hashlib.sha256).hexdigest()
    assert participant["platform_id"] == expected and "user_agent" not in participant
    assert participant["platform_data"]["SESSION_ID"] == hmac.new(b"a key the researcher keeps", b"session-77",
                                                                  hashlib.sha256).hexdigest()
    assert keyed["participants.json"] == keyed_again["participants.json"]  # the same key links exports
    assert unkeyed["participants.json"] != unkeyed_again["participants.json"]  # a key drawn per export links nothing

    key.write_text("short")
    with pytest.raises(CommandError) as refused:
        call_command("export_study", str(study.pk), "--out", str(tmp_path / "e.zip"), "--pseudonym-key-file", str(key))
    assert refused.value.returncode == 2 and "at least 16 characters" in str(refused.value)
    assert not (tmp_path / "e.zip").exists()
