"""Presigned addresses of the clips in the bucket (``MEDIA_BUCKET_URL``), made by the app
with AWS's signature version 4 for query strings, so that a participant's page names each
clip by the bucket's own address and the browser fetches it from the bucket, with no request
to the app in between.

boto3 signs an address with the moment it is made; here the address ends when ``clip_urls``'
addresses for the proxy end (``address_until``: the lifetime on, rounded up to an eighth of
it) and is signed as of its lifetime and an eighth before that: every page of those minutes,
from any gunicorn worker, names a clip by one address, so a clip fetched ahead for the next
page is the one that page plays. Where the
bucket's addresses point and its region are read once from an address boto3 signs, and the
key is the one django-storages' session finds (refreshed as boto3 refreshes a role's).
"""

from __future__ import annotations

import functools
import hashlib
import hmac
from dataclasses import dataclass
from datetime import datetime, timezone
from urllib.parse import parse_qsl, quote, urlsplit

import boto3
from django.conf import settings
from django.core.exceptions import ImproperlyConfigured
from django.core.files.storage import default_storage

from studyapp.server.clip_urls import address_until

ALGORITHM = "AWS4-HMAC-SHA256"
LONGEST_EXPIRY_S = 7 * 24 * 3600  # the longest an S3 presigned address may last
_PROBE = "stimuli/probe.mp4"


@dataclass(frozen=True)
class BucketAddress:
    """Where the bucket's objects are addressed: scheme and host, the path before a key, the region."""

    origin: str  # "https://s3.example" (with the port where there is one)
    path_before_key: str  # "/BUCKET/PREFIX/" for path-style addresses, "/PREFIX/" for virtual hosts
    region: str
    credentials: object  # botocore's Credentials (RefreshableCredentials for a role)


def presigned_clip_url(relative_path: str, now: float | None = None) -> str:
    """The bucket's address of the clip ``relative_path`` (``stimuli/<token>.mp4``), working for
    CLIP_URL_LIFETIME_S and at most an eighth more, its answer kept by the browser that long."""
    lifetime = settings.CLIP_URL_LIFETIME_S
    expires_s = int(lifetime * 9 / 8)
    bucket = _bucket_address(default_storage.bucket_name, default_storage.location, default_storage.endpoint_url)
    return sign_get(bucket, relative_path, address_until(now) - expires_s, expires_s,
                    {"response-cache-control": f"private, max-age={int(lifetime)}"})


def sign_get(bucket: BucketAddress, key: str, signed_at: int, expires_s: int, parameters: dict[str, str]) -> str:
    """A presigned GET of ``key`` (under the storage's prefix), signed as of ``signed_at``
    (seconds since the epoch) and lasting ``expires_s``: AWS's signature version 4 with the
    query-string parameters ``parameters`` signed in."""
    frozen = bucket.credentials.get_frozen_credentials()
    moment = datetime.fromtimestamp(signed_at, timezone.utc)
    day, stamp = moment.strftime("%Y%m%d"), moment.strftime("%Y%m%dT%H%M%SZ")
    scope = f"{day}/{bucket.region}/s3/aws4_request"
    query = {**parameters, "X-Amz-Algorithm": ALGORITHM, "X-Amz-Credential": f"{frozen.access_key}/{scope}",
             "X-Amz-Date": stamp, "X-Amz-Expires": str(expires_s), "X-Amz-SignedHeaders": "host"}
    if frozen.token:
        query["X-Amz-Security-Token"] = frozen.token
    canonical_query = "&".join(f"{_encode(name)}={_encode(value)}" for name, value in sorted(query.items()))
    path = bucket.path_before_key + quote(key, safe="/-_.~")
    host = urlsplit(bucket.origin).netloc
    canonical_request = f"GET\n{path}\n{canonical_query}\nhost:{host}\n\nhost\nUNSIGNED-PAYLOAD"
    to_sign = f"{ALGORITHM}\n{stamp}\n{scope}\n{hashlib.sha256(canonical_request.encode()).hexdigest()}"
    signing_key = f"AWS4{frozen.secret_key}".encode()
    for part in (day, bucket.region, "s3", "aws4_request"):
        signing_key = hmac.new(signing_key, part.encode(), hashlib.sha256).digest()
    signature = hmac.new(signing_key, to_sign.encode(), hashlib.sha256).hexdigest()
    return f"{bucket.origin}{path}?{canonical_query}&X-Amz-Signature={signature}"


def _encode(text: str) -> str:
    return quote(text, safe="-_.~")


@functools.lru_cache(maxsize=8)
def _bucket_address(bucket_name: str, location: str, endpoint_url: str | None) -> BucketAddress:
    """The storage's bucket as boto3 addresses it (the arguments are the cache's key: a test's
    or a deployment's bucket)."""
    credentials = _session(default_storage).get_credentials()
    if credentials is None:
        raise ImproperlyConfigured(f"no key for the bucket {bucket_name}: set AWS_ACCESS_KEY_ID and "
                                   "AWS_SECRET_ACCESS_KEY (or give the machine a role boto3 finds)")
    signed = urlsplit(default_storage.url(_PROBE))
    key_path = quote(f"{location.strip('/')}/{_PROBE}".lstrip("/"), safe="/-_.~")
    if not signed.path.endswith("/" + key_path):
        raise RuntimeError(f"boto3 addresses {_PROBE} in bucket {bucket_name} as {signed.path}, not ending in {key_path}")
    credential = dict(parse_qsl(signed.query))["X-Amz-Credential"]  # KEY/DAY/REGION/s3/aws4_request
    return BucketAddress(origin=f"{signed.scheme}://{signed.netloc}", path_before_key=signed.path[: -len(_PROBE)],
                         region=credential.split("/")[-3], credentials=credentials)


def _session(storage) -> boto3.Session:
    """The boto3 session django-storages makes for ``storage`` (its profile, or its key, or boto3's own search)."""
    if storage.session_profile:
        return boto3.Session(profile_name=storage.session_profile)
    return boto3.Session(aws_access_key_id=storage.access_key, aws_secret_access_key=storage.secret_key,
                         aws_session_token=storage.security_token)
