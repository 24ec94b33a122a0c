"""The clips in an S3-compatible bucket instead of MEDIA_ROOT (``MEDIA_BUCKET_URL``).

With a bucket, ``STORAGES["default"]`` is django-storages' S3 storage: the workers upload
each clip once it is rendered and checked whole (so a half-written clip is never in the
bucket), and the pages name each clip by a presigned address of the bucket that expires
after CLIP_URL_LIFETIME_S (``bucket_addresses``; the media view answers the app's own address
of a clip with a redirect there): the bucket (or a CDN in front of it) sends the bytes and
answers ranges, and no app thread is held while a clip downloads. Without a bucket every function here works on MEDIA_ROOT as
the app always has. The gallery and the reports stay under MEDIA_ROOT either way.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

from django.conf import settings
from django.core.exceptions import ImproperlyConfigured
from django.core.files import File
from django.core.files.storage import default_storage
from django.http import Http404, HttpRequest, HttpResponseBase, HttpResponseNotAllowed, HttpResponseRedirect

from studyapp.server.bucket_addresses import LONGEST_EXPIRY_S, presigned_clip_url

S3_STORAGE = "storages.backends.s3.S3Storage"
CLIPS_FOLDER = "stimuli"
# A clip's key is a plain file name in CLIPS_FOLDER; a hidden one is never a finished clip.
_CLIP_NAME = re.compile(r"[^/\\\0.][^/\\\0]*")


def bucket_storage(url: str, endpoint_url: str, lifetime_s: float) -> dict:
    """``STORAGES["default"]`` for ``url`` (``s3://BUCKET`` or ``s3://BUCKET/PREFIX``) on the
    S3 server at ``endpoint_url`` (empty: AWS itself), its addresses expiring after ``lifetime_s``.
    The key is the usual AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or the machine's role)."""
    parts = urlsplit(url)
    if parts.scheme != "s3" or not parts.netloc or parts.query or parts.fragment:
        raise ImproperlyConfigured(f"MEDIA_BUCKET_URL={url!r} is not s3://BUCKET or s3://BUCKET/PREFIX")
    if lifetime_s * 9 / 8 > LONGEST_EXPIRY_S:  # an address lasts an eighth longer (bucket_addresses)
        raise ImproperlyConfigured(f"CLIP_URL_LIFETIME_S={lifetime_s:g} is longer than a bucket's presigned address "
                                   f"may last with an eighth more ({LONGEST_EXPIRY_S} s, 7 days): at most "
                                   f"{LONGEST_EXPIRY_S * 8 // 9} s")
    if endpoint_url and urlsplit(endpoint_url).scheme not in ("http", "https"):
        raise ImproperlyConfigured(f"MEDIA_BUCKET_ENDPOINT_URL={endpoint_url!r} is not an http(s) address")
    options = {
        "bucket_name": parts.netloc,
        "location": parts.path.strip("/"),
        "endpoint_url": endpoint_url or None,
        "querystring_auth": True,  # the bucket stays private: every address is presigned
        "querystring_expire": int(lifetime_s),
        "file_overwrite": True,  # a clip's name is its token: a second upload replaces the first
        "default_acl": None,
        # Signature version 4: SeaweedFS refuses a version-2 address whose response-cache-control
        # holds a comma or an equals sign, and AWS asks for version 4 in its newer regions.
        "signature_version": "s3v4",
    }
    return {"BACKEND": S3_STORAGE, "OPTIONS": options}


def in_bucket() -> bool:
    return bool(settings.MEDIA_BUCKET_URL)


@contextlib.contextmanager
def clip_destination(relative_path: str) -> Iterator[Path]:
    """Where to write the clip at ``relative_path`` (a writer that replaces the file whole, as
    ``atomic_output`` does): MEDIA_ROOT's file itself, or with a bucket a scratch file that is
    uploaded once the block succeeds and deleted either way."""
    if not in_bucket():
        yield Path(settings.MEDIA_ROOT) / relative_path
        return
    with tempfile.TemporaryDirectory(prefix="clip-upload-") as scratch:
        path = Path(scratch) / Path(relative_path).name
        yield path
        with path.open("rb") as stream:
            stored = default_storage.save(relative_path, File(stream))
        if stored != relative_path:  # the clip's address is made from its path: another name would be lost
            raise RuntimeError(f"the bucket stored {relative_path} as {stored}")


def clip_exists(relative_path: str) -> bool:
    if in_bucket():
        return default_storage.exists(relative_path)
    return (Path(settings.MEDIA_ROOT) / relative_path).is_file()


def copy_clip(source: str, target: str) -> None:
    """The clip at ``source`` also at ``target``: in the bucket a copy, in MEDIA_ROOT a hard
    link where the file system has them."""
    if in_bucket():
        with default_storage.open(source) as stream:
            with clip_destination(target) as path, path.open("wb") as copy:
                shutil.copyfileobj(stream, copy)
        return
    media = Path(settings.MEDIA_ROOT)
    (media / target).parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(media / source, media / target)
    except OSError:  # another file system, or one without links
        shutil.copyfile(media / source, media / target)


def delete_clip(relative_path: str) -> None:
    """Delete the clip if it is there."""
    if in_bucket():
        default_storage.delete(relative_path)
    else:
        (Path(settings.MEDIA_ROOT) / relative_path).unlink(missing_ok=True)


def clip_redirect(request: HttpRequest, name: str) -> HttpResponseBase:
    """A redirect to the bucket's presigned, expiring address of the clip ``name`` in the clips'
    folder; any other key is not asked for. The browser may keep the redirect for an eighth of
    the address's life, as long as the address it leads to is the one the pages name."""
    if request.method not in ("GET", "HEAD"):
        return HttpResponseNotAllowed(["GET", "HEAD"])
    if not _CLIP_NAME.fullmatch(name):
        raise Http404("No such file")
    # The bucket's answer is kept by the browser as long as the address works (S3's
    # response-cache-control). Its Last-Modified cannot be left out: see the deployment page.
    # The pages name the bucket's address itself; this answers an address of the app's.
    response = HttpResponseRedirect(presigned_clip_url(f"{CLIPS_FOLDER}/{name}"))
    response["Cache-Control"] = f"private, max-age={int(settings.CLIP_URL_LIFETIME_S // 8)}"
    return response
