"""``backup.json``: what a backup holds (the engine and its dump's digest, every file's folder,
path, size and SHA-256, whether the files are in the backup or only listed), read back with
every field checked, so that a restore refuses a changed or foreign backup before it writes."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from studyapp.backups.database import DUMP_NAMES
from studyapp.backups.files import FileEntry

FORMAT, VERSION = "motion-study backup", 1
MANIFEST_NAME = "backup.json"
FILES_FOLDER = "files"
_SHA256 = re.compile(r"^[0-9a-f]{64}$")


class BackupRefused(ValueError):
    """A backup that is not restored; the message names what is wrong and where."""


@dataclass(frozen=True)
class BackupManifest:
    engine: str
    created: str  # ISO 8601, UTC
    code_version: str
    database_size: int
    database_sha256: str
    files_copied: bool  # False: the files are only listed (kept by other means, e.g. a volume snapshot)
    files: list[FileEntry]

    def to_json(self) -> str:
        return json.dumps({"format": FORMAT, "version": VERSION, "engine": self.engine, "created": self.created,
                           "code_version": self.code_version,
                           "database": {"file": DUMP_NAMES[self.engine], "bytes": self.database_size,
                                        "sha256": self.database_sha256},
                           "files_copied": self.files_copied, "files": [entry.as_dict() for entry in self.files]},
                          indent=1) + "\n"


def _field(record: dict, name: str, kind: type, where: str):
    value = record.get(name) if isinstance(record, dict) else None
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise BackupRefused(f"{where}: {name!r} is missing or not a {kind.__name__}")
    return value


def _entry(record: dict, folders: set[str], where: str) -> FileEntry:
    folder, path = _field(record, "folder", str, where), _field(record, "path", str, where)
    size, sha256 = _field(record, "bytes", int, where), _field(record, "sha256", str, where)
    parts = PurePosixPath(path).parts
    if folder not in folders:
        raise BackupRefused(f"{where}: no folder {folder!r} (one of {', '.join(sorted(folders))})")
    # A listed path never leaves its folder, whatever the backup's author wrote in it.
    if not parts or path.startswith("/") or any(part in ("..", ".") or part.startswith(".") for part in parts):
        raise BackupRefused(f"{where}: the path {path!r} is not a plain path inside its folder")
    if size < 0 or not _SHA256.match(sha256):
        raise BackupRefused(f"{where}: the size or the SHA-256 is not one")
    return FileEntry(folder, path, size, sha256)


def read_manifest(folder: Path, folders: set[str]) -> BackupManifest:
    """The manifest of the backup in ``folder``; BackupRefused naming the field that is wrong."""
    path = folder / MANIFEST_NAME
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise BackupRefused(f"{folder}: not a backup (no {MANIFEST_NAME})") from None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise BackupRefused(f"{path}: cannot be read ({error})") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT or record.get("version") != VERSION:
        raise BackupRefused(f"{path}: not a {FORMAT} of version {VERSION}")
    engine = _field(record, "engine", str, str(path))
    if engine not in DUMP_NAMES:
        raise BackupRefused(f"{path}: unknown engine {engine!r}")
    database = _field(record, "database", dict, str(path))
    if _field(database, "file", str, f"{path}, database") != DUMP_NAMES[engine]:
        raise BackupRefused(f"{path}, database: the file of a {engine} dump is {DUMP_NAMES[engine]}")
    database_size = _field(database, "bytes", int, f"{path}, database")
    database_sha256 = _field(database, "sha256", str, f"{path}, database")
    files = [_entry(entry, folders, f"{path}, files[{i}]")
             for i, entry in enumerate(_field(record, "files", list, str(path)))]
    return BackupManifest(engine, _field(record, "created", str, str(path)),
                          _field(record, "code_version", str, str(path)), database_size, database_sha256,
                          _field(record, "files_copied", bool, str(path)), files)
