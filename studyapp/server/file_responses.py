"""Serve files from a folder with HTTP range requests, so browsers can seek in videos.

Django's `static.serve` always sends the whole file, which leaves `<video>` unable
to seek (Safari will not even play it). This view answers `Range: bytes=...` with
206 Partial Content, says `Accept-Ranges: bytes`, rejects ranges past the end with
416, and refuses any path that resolves outside its folder or has a hidden (dot)
part. One range per request: a multi-range request gets the whole file, which HTTP
allows.
"""

import mimetypes
import re
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

from django.http import Http404, HttpRequest, HttpResponse, HttpResponseNotAllowed, StreamingHttpResponse
from django.utils.http import http_date

CHUNK_BYTES = 64 * 1024
# Where the proxy (deploy/Caddyfile) finds MEDIA_ROOT for the files this app tells it to send;
# no client can ask for it: the proxy sends every request to the app, which answers 404 there.
ACCEL_MEDIA_PREFIX = "/_accel/media/"
_SINGLE_RANGE = re.compile(r"^bytes=(\d*)-(\d*)$")
# No file has more bytes than this; longer numbers are read as "past any end" rather
# than handed to int(), which refuses more than 4,300 digits.
_MAX_DIGITS = 19


class UnsatisfiableRange(Exception):
    """The range names no byte of the file (answered with 416)."""


def _byte_position(digits: str) -> int:
    significant = digits.lstrip("0") or "0"
    return int(significant) if len(significant) <= _MAX_DIGITS else 10**_MAX_DIGITS


def parse_byte_range(header: str | None, size: int) -> tuple[int, int] | None:
    """The inclusive (first, last) byte a `Range` header asks for, or None for the whole file.

    A header that is absent, malformed or asks for several ranges is ignored, as
    RFC 9110 lets a server do; one that is well formed but misses the file raises.
    """
    if not header:
        return None
    match = _SINGLE_RANGE.match(header.strip())
    if not match:
        return None
    first_text, last_text = match.groups()
    if not first_text:
        if not last_text:
            return None
        suffix = _byte_position(last_text)  # "bytes=-N": the last N bytes
        if suffix == 0 or size == 0:
            raise UnsatisfiableRange
        return max(0, size - suffix), size - 1
    first = _byte_position(first_text)
    if last_text and _byte_position(last_text) < first:
        return None
    if first >= size:
        raise UnsatisfiableRange
    last = _byte_position(last_text) if last_text else size - 1
    return first, min(last, size - 1)


def _read_span(path: Path, first: int, length: int) -> Iterator[bytes]:
    with path.open("rb") as stream:
        stream.seek(first)
        remaining = length
        while remaining > 0:
            chunk = stream.read(min(CHUNK_BYTES, remaining))
            if not chunk:
                return
            remaining -= len(chunk)
            yield chunk


def _resolve_inside(document_root: Path, relative_path: str) -> Path:
    """The file at ``relative_path`` in ``document_root``, or Http404 where there is none to serve."""
    # Hidden names are work in progress (atomic_output's ".NAME.*.part" temporaries)
    # or private; a half-written video must never be served. No file name holds a NUL,
    # which the operating system's calls refuse outright.
    if "\0" in relative_path or any(part.startswith(".") for part in Path(relative_path).parts):
        raise Http404("No such file")
    root = document_root.resolve()
    # resolve() follows "..", absolute parts and symlinks, so the containment
    # test below sees where the file really is.
    target = (root / relative_path).resolve()
    if not target.is_relative_to(root) or not target.is_file():
        raise Http404("No such file")
    return target


def accel_redirect(request: HttpRequest, path: str, document_root: str | Path,
                   internal_prefix: str, max_age: int) -> HttpResponse:
    """An empty answer that tells the proxy in front to send `document_root/path` itself, from its
    own copy of the folder at ``internal_prefix`` (nginx's X-Accel-Redirect, which Caddy's
    ``handle_response`` reads too): the proxy answers ranges and caching, and no Python thread
    is held while a clip downloads. Its Cache-Control (private, ``max_age`` seconds) is the one
    the proxy sends with the file. The same files are refused as ``serve_with_ranges`` refuses.
    """
    if request.method not in ("GET", "HEAD"):
        return HttpResponseNotAllowed(["GET", "HEAD"])
    response = HttpResponse()
    for header, value in accel_headers(path, document_root, internal_prefix, max_age):
        response[header] = value
    return response


def accel_headers(path: str, document_root: str | Path, internal_prefix: str, max_age: int) -> list[tuple[str, str]]:
    """The headers of ``accel_redirect``'s answer for `document_root/path` (Http404 where it
    names no file to serve)."""
    root = Path(document_root).resolve()
    target = _resolve_inside(root, path)
    return [("X-Accel-Redirect", f"{internal_prefix.rstrip('/')}/{quote(target.relative_to(root).as_posix())}"),
            ("Cache-Control", f"private, max-age={max_age}")]


def serve_with_ranges(request: HttpRequest, path: str, document_root: str | Path,
                      reveal_mtime: bool = True) -> HttpResponse | StreamingHttpResponse:
    """A view answering GET and HEAD for `document_root/path`, with range support.

    ``reveal_mtime`` False leaves out Last-Modified: when each stimulus was rendered
    would tell a participant which clips came from the same system.
    """
    if request.method not in ("GET", "HEAD"):
        return HttpResponseNotAllowed(["GET", "HEAD"])
    target = _resolve_inside(Path(document_root), path)
    stat = target.stat()
    size = stat.st_size
    try:
        span = parse_byte_range(request.headers.get("Range"), size)
    except UnsatisfiableRange:
        response = HttpResponse(status=416)
        response["Content-Range"] = f"bytes */{size}"
        response["Accept-Ranges"] = "bytes"
        return response

    first, last = span if span is not None else (0, size - 1)
    length = last - first + 1 if size else 0
    body = _read_span(target, first, length) if request.method == "GET" else iter(())
    response = StreamingHttpResponse(body, status=206 if span is not None else 200)
    content_type, encoding = mimetypes.guess_type(target.name)
    response["Content-Type"] = content_type or "application/octet-stream"
    if encoding:
        response["Content-Encoding"] = encoding
    response["Content-Length"] = str(length)
    response["Accept-Ranges"] = "bytes"
    if reveal_mtime:
        response["Last-Modified"] = http_date(stat.st_mtime)
    if span is not None:
        response["Content-Range"] = f"bytes {first}-{last}/{size}"
    return response
