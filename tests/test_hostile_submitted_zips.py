"""Damaged zips of submitted motion: each is a 400 naming the member at fault, and nothing
is stored, where zipfile's own errors (Bad CRC-32, zlib errors, unsupported methods)
used to reach the researcher as a 500.

The cases are real damage made by editing a zip's bytes: a member whose directory entry
says 100 bytes but inflates to 5 MB, a flipped data byte, a broken deflate stream, a
compression method zipfile lacks, a local header that names another file, a member
offset past the end. A fuzz test then feeds ``read_zip`` drawn damage of every kind.
"""

from __future__ import annotations

import html
import io
import struct
import zipfile
from pathlib import Path

import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from studyapp.models import Study, System
from studyapp.stimuli.submissions import read_zip
from studyapp.stimuli.systems import UploadRefused

MEMBER = "lab/control-0.npz"
LOCAL_METHOD, LOCAL_CRC, LOCAL_USIZE, LOCAL_NAME = 8, 14, 22, 30
CENTRAL_METHOD, CENTRAL_USIZE, CENTRAL_OFFSET = 10, 24, 42


def _zip(data: bytes, method: int = zipfile.ZIP_DEFLATED) -> bytearray:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", method) as archive:
        archive.writestr(MEMBER, data)
    return bytearray(buffer.getvalue())


def _central(archive: bytearray) -> int:
    return archive.index(b"PK\x01\x02")


def _put(archive: bytearray, offset: int, fmt: str, value: int) -> bytearray:
    struct.pack_into(fmt, archive, offset, value)
    return archive


def inflates_past_its_directory() -> bytes:
    archive = _zip(bytes(5_000_000))
    _put(archive, LOCAL_USIZE, "<I", 100)
    return bytes(_put(archive, _central(archive) + CENTRAL_USIZE, "<I", 100))


def a_flipped_data_byte() -> bytes:
    archive = _zip(b"motion" * 100, zipfile.ZIP_STORED)
    archive[LOCAL_NAME + len(MEMBER) + 50] ^= 0xFF
    return bytes(archive)


def a_broken_deflate_stream() -> bytes:
    archive = _zip(bytes(range(256)) * 400)
    start = LOCAL_NAME + len(MEMBER)
    archive[start:start + 40] = b"\xff" * 40
    return bytes(archive)


def an_unknown_compression_method() -> bytes:
    archive = _zip(b"motion" * 100)
    _put(archive, LOCAL_METHOD, "<H", 99)
    return bytes(_put(archive, _central(archive) + CENTRAL_METHOD, "<H", 99))


def a_header_naming_another_file() -> bytes:
    archive = _zip(b"motion" * 100)
    archive[LOCAL_NAME:LOCAL_NAME + 3] = b"xyz"
    return bytes(archive)


def an_offset_past_the_end() -> bytes:
    archive = _zip(b"motion" * 100)
    return bytes(_put(archive, _central(archive) + CENTRAL_OFFSET, "<I", len(archive) + 1000))


DAMAGED = {"inflates past its directory": (inflates_past_its_directory, "Bad CRC-32"),
           "a flipped data byte": (a_flipped_data_byte, "Bad CRC-32"),
           "a broken deflate stream": (a_broken_deflate_stream, "Error -3"),
           "an unknown compression method": (an_unknown_compression_method, "compression method"),
           "a header naming another file": (a_header_naming_another_file, "differ"),
           "an offset past the end": (an_offset_past_the_end, "")}


@pytest.mark.django_db
@pytest.mark.parametrize("make, detail", DAMAGED.values(), ids=DAMAGED.keys())
def test_a_damaged_zip_of_submitted_motion_is_a_400_naming_the_member_and_stores_nothing(make, detail, client,
                                                                                        settings, tmp_path):
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    owner = User.objects.create_user("researcher")
    client.force_login(owner)
    study = Study.objects.create(owner=owner, title="Gait")

    response = client.post(f"/studies/{study.pk}/systems/", {
        "action": "motion", "name": "OtherLab", "role": "model", "motion": SimpleUploadedFile("motion.zip", make())})

    assert response.status_code == 400
    page = html.unescape(response.content.decode())
    assert f"{MEMBER}: a damaged zip member (" in page and detail in page and "Traceback" not in page
    assert not System.objects.exists()
    assert not Path(settings.CHECKPOINT_ROOT).exists() or not any(Path(settings.CHECKPOINT_ROOT).rglob("*"))


def _good_zip() -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(MEMBER, bytes(range(256)) * 8)
        archive.writestr("lab/control-1.bvh", b"HIERARCHY\nROOT Hips\n" * 20)
    return buffer.getvalue()


GOOD = _good_zip()


@st.composite
def damaged_zips(draw) -> bytes:
    """A good zip with bytes overwritten, cut, or repeated at drawn places (headers included)."""
    data = bytearray(GOOD)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["overwrite", "cut", "repeat"]))
        at = draw(st.integers(0, len(data) - 1))
        if kind == "overwrite":
            patch = draw(st.binary(min_size=1, max_size=8))
            data[at:at + len(patch)] = patch
        elif kind == "cut":
            del data[at:at + draw(st.integers(1, 64))]
        else:
            data[at:at] = data[at:at + draw(st.integers(1, 64))]
        if not data:
            data = bytearray(b"PK")
    return bytes(data)


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(damaged_zips())
def test_read_zip_refuses_any_damage_with_its_own_error(data):
    try:
        read_zip(io.BytesIO(data))
    except UploadRefused as refusal:
        assert str(refusal)
