"""The bucket's presigned clip addresses the app makes itself (``studyapp.server.bucket_addresses``):
the very address botocore would sign at the same moment, one address per clip for an eighth of
its lifetime, and a lifetime the bucket cannot sign refused at start-up. tests/test_media_bucket.py
fetches them from a real S3 server."""

from __future__ import annotations

import datetime
from urllib.parse import parse_qsl, urlsplit

import botocore.auth
import pytest
from django.core.exceptions import ImproperlyConfigured
from django.core.files.storage import default_storage

from studyapp.models import Stimulus
from studyapp.server.bucket_addresses import presigned_clip_url
from studyapp.server.media_bucket import bucket_storage

CLIP = "stimuli/0123456789abcdef0123456789abcdef.mp4"


@pytest.fixture
def bucket(settings, monkeypatch) -> None:
    """A bucket on an S3 server that is never asked: signing needs none."""
    monkeypatch.setenv("AWS_ACCESS_KEY_ID", "AKIDEXAMPLE")
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", "wJalrXUtnFEMI/K7MDENG+bPxRfiCYEXAMPLEKEY")
    monkeypatch.setenv("AWS_SESSION_TOKEN", "a role's token/with+signs=")
    settings.MEDIA_BUCKET_URL = "s3://study-media/production"
    settings.STORAGES = {**settings.STORAGES, "default": bucket_storage(
        settings.MEDIA_BUCKET_URL, "http://127.0.0.1:1", settings.CLIP_URL_LIFETIME_S)}


def botocore_at(moment: float, monkeypatch, expires_s: int, cache_control: str) -> str:
    """The address django-storages' boto3 signs for CLIP at ``moment``."""
    monkeypatch.setattr(botocore.auth, "get_current_datetime",
                        lambda: datetime.datetime.fromtimestamp(moment, datetime.timezone.utc).replace(tzinfo=None))
    return default_storage.url(CLIP, parameters={"ResponseCacheControl": cache_control}, expire=expires_s)


def parts(url: str) -> tuple:
    split = urlsplit(url)
    return split.scheme, split.netloc, split.path, sorted(parse_qsl(split.query))


def test_a_clip_address_is_the_one_botocore_signs_at_the_start_of_its_eighth(bucket, settings, monkeypatch):
    lifetime = settings.CLIP_URL_LIFETIME_S
    step = lifetime / 8
    now = 1_800_000_123.0
    ours = presigned_clip_url(CLIP, now=now)
    theirs = botocore_at(now // step * step, monkeypatch, int(lifetime + step), f"private, max-age={int(lifetime)}")

    assert parts(ours) == parts(theirs)  # the signature among the parameters
    assert ours.startswith(f"http://127.0.0.1:1/study-media/production/{CLIP}?")
    assert dict(parse_qsl(urlsplit(ours).query))["X-Amz-Security-Token"] == "a role's token/with+signs="


def test_a_clip_address_works_for_its_lifetime_and_an_eighth_at_most(bucket, settings):
    now = 1_800_000_123.0
    query = dict(parse_qsl(urlsplit(presigned_clip_url(CLIP, now=now)).query))
    signed = datetime.datetime.strptime(query["X-Amz-Date"], "%Y%m%dT%H%M%SZ").replace(tzinfo=datetime.timezone.utc)
    until = signed.timestamp() + int(query["X-Amz-Expires"])

    assert signed.timestamp() <= now and now + settings.CLIP_URL_LIFETIME_S <= until
    assert until <= now + settings.CLIP_URL_LIFETIME_S * 9 / 8


def test_the_pages_of_a_few_minutes_name_a_clip_by_one_bucket_address(bucket):
    start = 1_800_000_000.0
    assert len({presigned_clip_url(CLIP, now=start + seconds) for seconds in range(0, 60, 5)}) <= 2
    assert Stimulus(token=CLIP[8:-4]).video_url == presigned_clip_url(CLIP)  # what the pages name


def test_a_clip_lifetime_no_bucket_address_can_last_is_refused_at_start_up():
    with pytest.raises(ImproperlyConfigured, match=r"CLIP_URL_LIFETIME_S=600000 .* at most 537600 s"):
        bucket_storage("s3://study-media", "", 600_000)


def test_a_bucket_without_a_key_is_named_rather_than_signed_for(settings, monkeypatch):
    for name in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN", "AWS_PROFILE"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("AWS_SHARED_CREDENTIALS_FILE", "/nonexistent")
    monkeypatch.setenv("AWS_CONFIG_FILE", "/nonexistent")
    monkeypatch.setenv("AWS_EC2_METADATA_DISABLED", "true")
    settings.MEDIA_BUCKET_URL = "s3://keyless-media"
    settings.STORAGES = {**settings.STORAGES, "default": bucket_storage(
        settings.MEDIA_BUCKET_URL, "http://127.0.0.1:1", settings.CLIP_URL_LIFETIME_S)}
    with pytest.raises(ImproperlyConfigured, match="no key for the bucket keyless-media: set AWS_ACCESS_KEY_ID"):
        presigned_clip_url(CLIP)
