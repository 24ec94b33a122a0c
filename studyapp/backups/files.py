"""The files a backup keeps, folder by folder: listed with their size and SHA-256, copied
into the backup (or only listed, where the folders are kept by other means, such as a volume
snapshot), checked against the listing, and put back.

Hidden names are left out: they are files still being written (``generation.files``)."""

from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from django.conf import settings

from generation.files import atomic_output
from studyapp.stimuli.sources import sampled_folder

CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class FileEntry:
    folder: str  # a name of ``backed_up_folders``
    path: str  # relative to the folder, with "/"
    size: int
    sha256: str

    def as_dict(self) -> dict:
        return {"folder": self.folder, "path": self.path, "bytes": self.size, "sha256": self.sha256}


def backed_up_folders() -> dict[str, Path]:
    """The folders whose files the rows name: clips, gallery and reports (``media``), uploaded
    checkpoints and submitted motion (``checkpoints``), and the sampled motion the clips were
    rendered from (``sampled``)."""
    return {"media": Path(settings.MEDIA_ROOT), "checkpoints": Path(settings.CHECKPOINT_ROOT),
            "sampled": sampled_folder()}


def _files_under(root: Path) -> Iterator[Path]:
    for folder, subfolders, names in os.walk(root):
        subfolders[:] = sorted(name for name in subfolders if not name.startswith("."))
        for name in sorted(names):
            if not name.startswith(".") and Path(folder, name).is_file():
                yield Path(folder, name)


def _copy_hashing(source: Path, target: Path | None) -> tuple[int, str]:
    """(size, SHA-256) of ``source``, copied to ``target`` on the way unless it is None."""
    digest, size = hashlib.sha256(), 0
    with source.open("rb") as reading:
        writing = target.open("wb") if target is not None else None
        try:
            while chunk := reading.read(CHUNK_BYTES):
                digest.update(chunk)
                size += len(chunk)
                if writing is not None:
                    writing.write(chunk)
        finally:
            if writing is not None:
                writing.close()
    return size, digest.hexdigest()


def list_files(copy_into: Path | None) -> list[FileEntry]:
    """Every file of the backed-up folders, copied under ``copy_into/<folder>/`` unless it is None."""
    entries = []
    for name, root in backed_up_folders().items():
        for path in _files_under(root):
            relative = path.relative_to(root).as_posix()
            target = None
            if copy_into is not None:
                target = copy_into / name / relative
                target.parent.mkdir(parents=True, exist_ok=True)
            size, sha256 = _copy_hashing(path, target)
            entries.append(FileEntry(name, relative, size, sha256))
    return entries


def size_and_sha256(path: Path) -> tuple[int, str]:
    return _copy_hashing(path, None)


def file_problem(path: Path, size: int, sha256: str) -> str | None:
    """What is wrong with ``path`` as a file listed with ``size`` and ``sha256``; None when its bytes are those."""
    if not path.is_file():
        return "missing"
    found_size, found_sha256 = size_and_sha256(path)
    if (found_size, found_sha256) != (size, sha256):
        return f"{found_size} bytes of SHA-256 {found_sha256[:12]}…, not the listed {size} bytes of {sha256[:12]}…"
    return None


def place(source: Path, target: Path) -> None:
    """Copy ``source`` to ``target`` atomically (a reader never sees half of it)."""
    with atomic_output(target) as work:
        shutil.copyfile(source, work)
