"""Zips that come from outside (submitted motion, study bundles), read member by member.

zipfile is never asked to extract: a member's name becomes a path only through
``member_path``, which refuses absolute names and ``..`` (zip slip), and a member is
read only through ``copy_member``, which stops one byte past the size the central
directory declares (a member that inflates beyond it, a zip bomb, is refused there).
``checked_members`` refuses an archive of too many members, or one whose members
declare more than the caller's limit in all, before any is read.

A damaged archive fails in many ways inside zipfile (a CRC that does not match, a
member that inflates past its declared size, a cut deflate stream, a compression method
it lacks, headers that contradict each other); each is refused naming the member.
"""

from __future__ import annotations

import struct
import zipfile
import zlib
from contextlib import contextmanager
from collections.abc import Iterator
from pathlib import PurePosixPath
from typing import BinaryIO

MAX_MEMBERS = 10_000
CHUNK_BYTES = 1 << 20
DAMAGED = (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, OSError, ValueError, struct.error)


class ZipRefused(ValueError):
    """A zip, or a member of one, that is not read; the message names the member and the problem."""


@contextmanager
def opened_zip(stream: BinaryIO | str) -> Iterator[zipfile.ZipFile]:
    """The archive of ``stream`` (a file object or a path); ZipRefused if it is no zip."""
    try:
        archive = zipfile.ZipFile(stream)
    except DAMAGED as error:
        raise ZipRefused(f"not a zip file ({error})") from None
    with archive:
        yield archive


def checked_members(archive: zipfile.ZipFile, total_limit: int) -> list[zipfile.ZipInfo]:
    """The archive's files (folders left out), at most ``MAX_MEMBERS`` of them, declaring
    at most ``total_limit`` bytes together, none encrypted."""
    members = [info for info in archive.infolist() if not info.is_dir()]
    if len(members) > MAX_MEMBERS:
        raise ZipRefused(f"the zip holds {len(members)} files; at most {MAX_MEMBERS}")
    declared = sum(info.file_size for info in members)
    if declared > total_limit:
        raise ZipRefused(f"the zip unpacks to {declared / 1e6:.3g} MB, over the {total_limit / 1e6:g} MB limit")
    for info in members:
        if info.flag_bits & 0x1:
            raise ZipRefused(f"{info.filename}: encrypted zip members are not read")
    return members


def member_path(name: str) -> PurePosixPath:
    """A member's name as a relative path that stays inside any folder it is placed in."""
    path = PurePosixPath(name)
    if (not name or "\\" in name or "\0" in name or path.is_absolute() or ":" in path.parts[0]
            or any(part in ("", ".", "..") for part in name.split("/"))):
        raise ZipRefused(f"{name!r}: a member name must be a relative path without '..' (it would be "
                         "written outside the folder it is read into)")
    return path


def copy_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, out: BinaryIO, limit: int) -> int:
    """Copy a member's bytes to ``out``, never more than it declares nor than ``limit``; how many."""
    if info.file_size > limit:
        raise ZipRefused(f"{info.filename}: {info.file_size / 1e6:.3g} MB, over the {limit / 1e6:g} MB limit "
                         "for such a file")
    copied = 0
    try:
        with archive.open(info) as member:
            while chunk := member.read(min(CHUNK_BYTES, info.file_size + 1 - copied)):
                copied += len(chunk)
                if copied > info.file_size:
                    raise ZipRefused(f"{info.filename}: unpacks to more than its declared {info.file_size} bytes")
                out.write(chunk)
    except ZipRefused:
        raise
    except DAMAGED as error:
        raise ZipRefused(f"{info.filename}: a damaged zip member ({error})") from None
    return copied


__all__ = ["MAX_MEMBERS", "ZipRefused", "checked_members", "copy_member", "member_path", "opened_zip"]
