"""Writing a backup: the database's snapshot first, then the files, so that every file a row
of the snapshot names is in the backup (files are written before the rows that name them,
under names never reused, and removed only with their rows)."""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

from generation.checkpoints.checkpoint import code_version
from generation.files import atomic_folder
from studyapp.backups.database import DUMP_NAMES, dump, engine
from studyapp.backups.files import list_files, size_and_sha256
from studyapp.backups.manifest import FILES_FOLDER, MANIFEST_NAME, BackupManifest


def write_backup(out: Path, copy_files: bool) -> BackupManifest:
    """Write a backup folder at ``out`` (absent or empty); with ``copy_files`` False the files are
    only listed. Nothing is left at ``out`` on an error."""
    with atomic_folder(out) as work:
        dumped = work / DUMP_NAMES[engine()]
        dump(dumped)
        size, sha256 = size_and_sha256(dumped)
        files = list_files(work / FILES_FOLDER if copy_files else None)
        manifest = BackupManifest(engine(), datetime.now(timezone.utc).isoformat(timespec="seconds"),
                                  code_version(), size, sha256, copy_files, files)
        (work / MANIFEST_NAME).write_text(manifest.to_json(), encoding="utf-8")
    return manifest
