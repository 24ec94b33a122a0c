"""A bundle read into a scratch folder, every file checked before anything is imported.

The zip is read as every zip from outside is (``studyapp.server.uploads.zips``): at most
``MAX_MEMBERS`` members, no encrypted one, no name that leaves the folder (zip slip), no
member past its declared size; and here also no member past the upload limit of its kind
(a checkpoint's, a video's, a definition's, a ratings table's, the records' limit for the
JSON records, the motion limit for the rest) nor all of them past
``MAX_BUNDLE_UPLOAD_BYTES``. The manifest is read first and its format version checked;
then every member must be listed in it, with the SHA-256 and size it lists, and every
listed file must be there. The first problem refuses the whole bundle with
``BundleRefused`` naming the file.
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from django.conf import settings

from studyapp.bundles import records
from studyapp.bundles.manifest import MANIFEST_NAME, MAX_MANIFEST_BYTES, BundleRefused, HashingWriter, Manifest, parse_manifest
from studyapp.definitions.reading import MAX_DEFINITION_BYTES
from studyapp.server.uploads.zips import ZipRefused, checked_members, copy_member, member_path, opened_zip


@dataclass(frozen=True)
class ReadBundle:
    folder: Path  # every file of the bundle, checked against the manifest
    manifest: Manifest

    def path(self, name: str) -> Path:
        return self.folder / name


def member_limit(name: str) -> int:
    """The most bytes a file of the bundle may hold: the upload limit of its kind (the
    records, read whole into memory, the smallest)."""
    if name.startswith(records.CHECKPOINTS):
        return settings.MAX_CHECKPOINT_UPLOAD_BYTES
    if name.startswith(records.VIDEOS):
        return settings.MAX_VIDEO_UPLOAD_BYTES
    if name == records.DEFINITION_FILE:
        return MAX_DEFINITION_BYTES
    if name == records.RATINGS_FILE:
        return settings.MAX_RATINGS_UPLOAD_BYTES
    if name in records.RECORD_FILES:
        return settings.MAX_RECORD_UPLOAD_BYTES
    return settings.MAX_MOTION_UPLOAD_BYTES


def _manifest(archive: zipfile.ZipFile, members: dict[str, zipfile.ZipInfo]) -> Manifest:
    info = members.get(MANIFEST_NAME)
    if info is None:
        raise BundleRefused(f"no {MANIFEST_NAME}: not a study bundle (export_study writes one)")
    text = io.BytesIO()
    copy_member(archive, info, text, MAX_MANIFEST_BYTES)
    return parse_manifest(text.getvalue())


def read_bundle(stream: BinaryIO | str, folder: Path) -> ReadBundle:
    """The bundle in ``stream`` (a file object or a path) unpacked into ``folder``, every
    file as its manifest lists it; BundleRefused naming the first problem."""
    try:
        with opened_zip(stream) as archive:
            members: dict[str, zipfile.ZipInfo] = {}
            for info in checked_members(archive, settings.MAX_BUNDLE_UPLOAD_BYTES):
                member_path(info.filename)
                if info.filename in members:
                    raise BundleRefused(f"{info.filename}: in the bundle twice")
                members[info.filename] = info
            manifest = _manifest(archive, members)
            for name, info in members.items():
                if name == MANIFEST_NAME:
                    continue
                listed = manifest.files.get(name)
                if listed is None:
                    raise BundleRefused(f"{name}: not listed in {MANIFEST_NAME} (a file added after the export)")
                target = folder / member_path(name)
                try:
                    target.parent.mkdir(parents=True, exist_ok=True)
                    with target.open("wb") as out:
                        written = HashingWriter(out)
                        copy_member(archive, info, written, member_limit(name))
                except OSError as error:  # a name that is also a folder's, or one this file system refuses
                    raise BundleRefused(f"{name}: cannot be unpacked ({error.strerror})") from None
                if written.entry != listed:
                    raise BundleRefused(f"{name}: its SHA-256 or size differs from {MANIFEST_NAME}'s (the file was "
                                        "changed or damaged after the export)")
    except ZipRefused as error:
        raise BundleRefused(str(error)) from None
    if missing := sorted(set(manifest.files) - set(members)):
        raise BundleRefused(f"{missing[0]}: listed in {MANIFEST_NAME} but not in the bundle"
                            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    return ReadBundle(folder, manifest)


__all__ = ["ReadBundle", "member_limit", "read_bundle"]
