"""The clips in an S3 bucket (``MEDIA_BUCKET_URL``), on a real S3 server this module starts
(SeaweedFS, ``tests/s3_server.py``): a study's clips rendered by the workers' code and uploaded
ones go to the bucket and nowhere under MEDIA_ROOT, a participant's page names each clip by an
expiring address of the bucket that serves the same bytes (with ranges) and stops when it
expires, and the study is rated and reported. Without a bucket the clips stay in MEDIA_ROOT, as the
rest of the suite checks."""

from __future__ import annotations

import hashlib
import time
import urllib.error
import urllib.request

import pytest
from django.core.exceptions import ImproperlyConfigured
from django.core.files.base import ContentFile
from django.core.files.storage import default_storage
from django.core.management import CommandError, call_command
from django.test import Client

from studyapp.models import Study
from studyapp.researchers.results.reports import create_study_report, report_folder
from studyapp.researchers.setup.duplication import duplicate_study
from studyapp.researchers.setup.removal import delete_files
from studyapp.server.bucket_addresses import presigned_clip_url
from studyapp.server.media_bucket import bucket_storage
from studyapp.stimuli.clips import claim
from tests.s3_server import s3_server
from tests.test_hostile_bundles import small_study
from tests.test_report_presentation import rate_everything
from tests.test_study_researcher import files, researcher, site  # noqa: F401 (fixtures)

pytestmark = [pytest.mark.django_db, pytest.mark.slow]


@pytest.fixture(scope="module")
def s3():
    with s3_server() as server:
        yield server


@pytest.fixture
def bucket(settings, site, s3, monkeypatch) -> str:
    """This test's media in the bucket under a prefix of its own; the prefix."""
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", s3.access_key)
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", s3.secret_key)
    prefix = f"deployment-{site.name}"
    settings.MEDIA_BUCKET_URL = f"s3://{s3.bucket}/{prefix}"
    settings.STORAGES = {**settings.STORAGES, "default": bucket_storage(
        settings.MEDIA_BUCKET_URL, s3.endpoint_url, settings.CLIP_URL_LIFETIME_S)}
    return prefix


def fetch(url: str, headers: dict | None = None) -> tuple[int, bytes]:
    with urllib.request.urlopen(urllib.request.Request(url, headers=headers or {}), timeout=30) as answer:
        return answer.status, answer.read()


def files_under(root) -> list[str]:
    return sorted(str(path.relative_to(root)) for path in root.rglob("*") if path.is_file()) if root.exists() else []


def test_a_study_generated_rated_and_reported_keeps_its_clips_only_in_the_bucket(researcher, files, bucket, s3,
                                                                                 settings):
    study = small_study(researcher, files)  # MoGlow's clips rendered as a worker renders them, a BAD one uploaded
    clips = list(study.stimuli.all())
    assert len(clips) >= 3 and all(clip.status == "done" for clip in clips)
    assert files_under(settings.MEDIA_ROOT) == []
    assert s3.keys(f"{bucket}/") == sorted(f"{bucket}/{clip.relative_path}" for clip in clips)
    assert claim(clips[0].pk, clips[0].task_id) is None  # a worker finds the clip done, in the bucket

    for clip in clips:
        target = clip.video_url  # what a participant's page names: the bucket's own address
        assert target.startswith(f"{s3.endpoint_url}/{s3.bucket}/{bucket}/{clip.relative_path}?")
        answer = Client().get(f"/media/{clip.relative_path}")  # the app's address of it, with no login
        assert answer.status_code == 302 and answer["Location"] == target and "private" in answer["Cache-Control"]
        found = s3.client().get_object(Bucket=s3.bucket, Key=f"{bucket}/{clip.relative_path}")
        stored = found["Body"].read()
        assert found["ContentType"] == "video/mp4"  # what Safari needs to play it
        assert stored[4:8] == b"ftyp" and fetch(target) == (200, stored)
        assert fetch(target, {"Range": "bytes=0-99"}) == (206, stored[:100])  # the video seeks
    with pytest.raises(urllib.error.HTTPError) as refused:  # the bucket itself is private
        fetch(target.partition("?")[0])
    assert refused.value.code == 403

    rate_everything(study, lambda system, k: 1 + k if system == "BAD" else 3 + k % 2)
    digest = create_study_report(Study.objects.get(pk=study.pk), researcher.pk)
    assert files_under(report_folder(settings.MEDIA_ROOT, digest))  # the report stays in MEDIA_ROOT
    assert not (settings.MEDIA_ROOT / "stimuli").exists()


def answer_of(url: str, **headers: str) -> tuple[int, dict[str, str]]:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, headers=headers), timeout=30) as answer:
            answer.read()
            return answer.status, dict(answer.headers)
    except urllib.error.HTTPError as refused:
        return refused.code, dict(refused.headers)


def test_the_bucket_sends_a_clip_kept_as_long_as_its_address_works_but_dated_by_its_upload(bucket, settings):
    """The presigned address asks for the Cache-Control of the address's lifetime, which the
    bucket honours. What it cannot be asked to leave out (S3 overrides no Last-Modified) is
    pinned here as the known leak the deployment page names: the clip's upload time, in its
    Last-Modified and in its answers to conditional requests."""
    default_storage.save("stimuli/0123abcd.mp4", ContentFile(b"\0\0\0\x18ftypmp42" + bytes(4096)))
    redirect = Client().get("/media/stimuli/0123abcd.mp4")
    assert redirect.status_code == 302
    status, headers = answer_of(redirect["Location"])
    assert status == 200 and headers["Cache-Control"] == f"private, max-age={int(settings.CLIP_URL_LIFETIME_S)}"
    assert answer_of(redirect["Location"], Range="bytes=0-9")[0] == 206
    uploaded = headers["Last-Modified"]  # the leak: when the clip went into the bucket
    assert answer_of(redirect["Location"], **{"If-Modified-Since": uploaded})[0] == 304
    assert headers["Etag"].strip('"') == hashlib.md5(b"\0\0\0\x18ftypmp42" + bytes(4096)).hexdigest()  # no time in it


def test_the_bucket_refuses_a_clip_address_once_it_has_expired(bucket, settings):
    default_storage.save("stimuli/0123abcd.mp4", ContentFile(b"\0\0\0\x18ftypmp42" + bytes(64)))
    lifetime = settings.CLIP_URL_LIFETIME_S
    assert answer_of(presigned_clip_url("stimuli/0123abcd.mp4"))[0] == 200
    assert answer_of(presigned_clip_url("stimuli/0123abcd.mp4", now=time.time() - lifetime * 9 / 8 - 60))[0] == 403


def test_a_clip_request_names_a_clip_file_or_is_refused_without_asking_the_bucket(bucket):
    client = Client()
    for path in ("stimuli/.hidden.mp4", "stimuli/a/b.mp4", "stimuli/", "stimuli/a%5Cb.mp4"):
        assert client.get(f"/media/{path}").status_code == 404, path
    assert client.post("/media/stimuli/clip.mp4").status_code == 405


def test_a_duplicated_study_has_copies_of_its_clips_in_the_bucket_and_deleting_them_deletes_them(researcher, files,
                                                                                                  bucket, s3):
    study = small_study(researcher, files)
    copy = duplicate_study(study)
    key = lambda clip: f"{bucket}/{clip.relative_path}"  # noqa: E731
    read = lambda clip: s3.client().get_object(Bucket=s3.bucket, Key=key(clip))["Body"].read()  # noqa: E731
    originals = {clip.content_key: read(clip) for clip in study.stimuli.all()}
    assert {clip.content_key: read(clip) for clip in copy.stimuli.all()} == originals
    clips = list(study.stimuli.all())
    study.delete()
    delete_files(clips)
    assert s3.keys(f"{bucket}/") == sorted(key(clip) for clip in copy.stimuli.all())


def test_the_bucket_address_must_be_an_s3_url_naming_a_bucket():
    for url in ("https://example.com/media", "s3://", "s3://bucket?region=x"):
        with pytest.raises(ImproperlyConfigured, match="MEDIA_BUCKET_URL="):
            bucket_storage(url, "", 3600)
    with pytest.raises(ImproperlyConfigured, match="MEDIA_BUCKET_ENDPOINT_URL="):
        bucket_storage("s3://media", "127.0.0.1:9000", 3600)


def test_a_backup_is_refused_while_the_clips_are_in_the_bucket_rather_than_written_without_them(bucket, tmp_path):
    with pytest.raises(CommandError, match="no backup written: the clips are in the bucket") as refused:
        call_command("backup", str(tmp_path / "backup"))
    assert refused.value.returncode == 2 and not (tmp_path / "backup").exists()
