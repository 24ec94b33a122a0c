"""The manifest of a study bundle: what each file is, so nothing in it can be changed unseen.

``manifest.json`` lists every other file of the bundle with its SHA-256 and size, the
bundle's format and version, and the code that wrote it (``generation.checkpoint``'s
``code_version``, the version checkpoints record, and the stimuli's ``CODE_VERSION``,
which their content keys hold). A reader refuses a version it does not know, and any
file that is not listed, listed but absent, or whose bytes differ from the listing.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from generation.store import SHA256_HEX
from studyapp.server.uploads.bounded_reading import ReadRefused, json_value

FORMAT = "motion-study bundle"
VERSION = 1
SUPPORTED_VERSIONS = (1,)
MANIFEST_NAME = "manifest.json"
MAX_MANIFEST_BYTES = 10_000_000  # 10,000 entries of a few hundred bytes each, many times over


class BundleRefused(ValueError):
    """A bundle that is not imported; the message names the file and what is wrong with it."""


@dataclass(frozen=True)
class Entry:
    sha256: str
    size: int


@dataclass(frozen=True)
class Manifest:
    version: int
    code_version: str
    stimuli_code_version: str
    files: dict[str, Entry]

    def to_json(self) -> str:
        return json.dumps({"format": FORMAT, "version": self.version, "code_version": self.code_version,
                           "stimuli_code_version": self.stimuli_code_version,
                           "files": {name: {"sha256": entry.sha256, "bytes": entry.size}
                                     for name, entry in sorted(self.files.items())}}, indent=1) + "\n"


def entry_of(data: bytes) -> Entry:
    return Entry(hashlib.sha256(data).hexdigest(), len(data))


class HashingWriter:
    """A binary file that hashes what is written to it, for files too large to hold in memory."""

    def __init__(self, out: BinaryIO) -> None:
        self.out, self.digest, self.size = out, hashlib.sha256(), 0

    def write(self, chunk: bytes) -> int:
        self.digest.update(chunk)
        self.size += len(chunk)
        return self.out.write(chunk)

    @property
    def entry(self) -> Entry:
        return Entry(self.digest.hexdigest(), self.size)


def file_entry(path: Path) -> Entry:
    digest, size = hashlib.sha256(), 0
    with path.open("rb") as stream:
        while chunk := stream.read(1 << 20):
            digest.update(chunk)
            size += len(chunk)
    return Entry(digest.hexdigest(), size)


def parse_manifest(text: bytes) -> Manifest:
    """The manifest of a bundle (BundleRefused naming the field that is wrong)."""
    def refuse(problem: str) -> BundleRefused:
        return BundleRefused(f"{MANIFEST_NAME}: {problem}")

    try:
        data = json_value(text, MANIFEST_NAME, MAX_MANIFEST_BYTES)
    except ReadRefused as error:
        raise BundleRefused(str(error)) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise refuse(f"not the manifest of a study bundle (its format is not {FORMAT!r})")
    version = data.get("version")
    if type(version) is not int or version not in SUPPORTED_VERSIONS:
        raise refuse(f"format version {version!r} is not one this server reads "
                     f"({', '.join(map(str, SUPPORTED_VERSIONS))}): export the study again with this version")
    files = data.get("files")
    if not isinstance(files, dict):
        raise refuse("'files' must be an object of file names")
    entries = {}
    for name, entry in files.items():
        if not (isinstance(entry, dict) and isinstance(entry.get("sha256"), str) and SHA256_HEX.fullmatch(entry["sha256"])
                and type(entry.get("bytes")) is int and entry["bytes"] >= 0):
            raise refuse(f"the entry of {name!r} must be {{\"sha256\": 64 hex digits, \"bytes\": a size}}")
        entries[name] = Entry(entry["sha256"], entry["bytes"])
    versions = [data.get(field) for field in ("code_version", "stimuli_code_version")]
    if not all(isinstance(value, str) for value in versions):
        raise refuse("'code_version' and 'stimuli_code_version' must be strings")
    return Manifest(version, versions[0], versions[1], entries)


__all__ = ["BundleRefused", "Entry", "HashingWriter", "MANIFEST_NAME", "Manifest", "VERSION", "entry_of",
           "file_entry", "parse_manifest"]
