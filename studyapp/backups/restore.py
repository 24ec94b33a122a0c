"""Restoring a backup into an empty database and the deployment's folders: everything is
checked against the manifest before anything is written, and the files placed are removed
again should the database then fail to load."""

from __future__ import annotations

from pathlib import Path

from django.db import connection

from studyapp.backups.database import DUMP_NAMES, engine, load, table_count
from studyapp.backups.files import backed_up_folders, file_problem, place
from studyapp.backups.manifest import FILES_FOLDER, BackupManifest, BackupRefused, read_manifest

SHOWN_PROBLEMS = 10


def _checked_files(folder: Path, manifest: BackupManifest) -> list[tuple[Path, Path]]:
    """(source in the backup, target) of each file to copy; BackupRefused naming every file
    that is missing or changed, or that would replace a different file."""
    roots = backed_up_folders()
    problems, copies = [], []
    for entry in manifest.files:
        target = roots[entry.folder] / entry.path
        if not manifest.files_copied:
            if problem := file_problem(target, entry.size, entry.sha256):
                problems.append(f"{target}: {problem}")
            continue
        source = folder / FILES_FOLDER / entry.folder / entry.path
        if problem := file_problem(source, entry.size, entry.sha256):
            problems.append(f"{source}: {problem}")
        elif target.exists():
            if file_problem(target, entry.size, entry.sha256):
                problems.append(f"{target}: a different file is there already")
        else:
            copies.append((source, target))
    if problems:
        more = f" and {len(problems) - SHOWN_PROBLEMS} more" if len(problems) > SHOWN_PROBLEMS else ""
        raise BackupRefused(f"{len(problems)} of the files do not match the backup's manifest, nothing was restored: "
                            + "; ".join(problems[:SHOWN_PROBLEMS]) + more)
    return copies


def restore_backup(folder: Path) -> BackupManifest:
    """Bring the backup in ``folder`` back; BackupRefused (nothing written) for a backup that does
    not match its manifest, of another engine, or a database that is not empty."""
    manifest = read_manifest(folder, set(backed_up_folders()))
    if manifest.engine != engine():
        raise BackupRefused(f"{folder}: a backup of a {manifest.engine} database, and DATABASE_URL names a "
                            f"{engine()} one; restore it into {manifest.engine} (a study moves between servers "
                            "with export_study and import_study)")
    if tables := table_count():
        raise BackupRefused(f"the database {connection.settings_dict['NAME']} is not empty ({tables} tables): "
                            "restore into a new database that nothing has migrated, nothing was restored")
    dumped = folder / DUMP_NAMES[manifest.engine]
    if problem := file_problem(dumped, manifest.database_size, manifest.database_sha256):
        raise BackupRefused(f"{dumped}: {problem}; nothing was restored")
    copies = _checked_files(folder, manifest)
    placed = []
    try:
        for source, target in copies:
            place(source, target)
            placed.append(target)
        load(dumped)
    except BaseException:
        for target in placed:
            target.unlink(missing_ok=True)
        raise
    return manifest
