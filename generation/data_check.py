"""Is the motion data at hand the data the committed models learnt from? (``check-data``)

Two answers, each from what the repository records:

- per folder, which takes are expected, found, missing, changed or not expected:
  ``models/TRAINING-DATA.sha256`` lists every BVH file and label side file of the two
  Bandai-Namco folders as the committed models saw them, with its SHA-256;
- per committed model, whether it applies: the data fingerprint its checkpoint records
  is computed again over the folders with the dataset options it records, as the demo
  and the study app compare them. A model that does not apply is refused by the demo,
  which then asks for its own training (``DEMO_TRAIN=1``).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from .checkpoint import read_meta
from .motion.clip_files import choose_files, find_bvh_files, motion_folders
from .motion.dataset import fingerprint
from .motion.dataset_options import DatasetOptions

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / "models"
MANIFEST = MODELS / "TRAINING-DATA.sha256"


@dataclass
class FolderCheck:
    """One motion folder against the expected data set whose file names it shares most."""

    folder: Path
    expected_set: str | None  # None: no expected set shares a file name with it
    expected: int = 0
    found: int = 0
    missing: list[str] = field(default_factory=list)
    changed: list[str] = field(default_factory=list)
    unexpected: list[str] = field(default_factory=list)

    @property
    def as_expected(self) -> bool:
        return self.expected_set is not None and not (self.missing or self.changed or self.unexpected)


@dataclass
class ModelCheck:
    file: str
    applies: bool
    why: str


def read_manifest(path: Path = MANIFEST) -> dict[str, dict[str, str]]:
    """Expected files by data set: {set: {file name: SHA-256}}."""
    sets: dict[str, dict[str, str]] = {}
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        digest, _, name = line.partition("  ")
        data_set, _, file = name.partition("/")
        if len(digest) != 64 or not file:
            raise ValueError(f"{path}:{number}: expected 'SHA-256  SET/FILE', found {line!r}")
        sets.setdefault(data_set, {})[file] = digest
    return sets


def check_folder(folder: Path, sets: dict[str, dict[str, str]]) -> FolderCheck:
    """The folder's takes against the expected set: a take is its BVH file and its label side file."""
    found = {path.name: path for path in find_bvh_files([folder])}
    best = max(sets, key=lambda name: len(sets[name].keys() & found.keys()), default=None)
    if best is None or not sets[best].keys() & found.keys():
        return FolderCheck(folder, None, found=len(found))
    expected = sets[best]
    takes = {name for name in expected if name.endswith(".bvh")}

    def differs(name: str) -> bool:
        files = [found[name], found[name].with_suffix(".json")]
        return any(expected.get(file.name) != (hashlib.sha256(file.read_bytes()).hexdigest() if file.is_file() else None)
                   for file in files)

    return FolderCheck(folder, best, expected=len(takes), found=len(found),
                       missing=sorted(takes - found.keys()),
                       changed=sorted(name for name in takes & found.keys() if differs(name)),
                       unexpected=sorted(found.keys() - takes))


def recorded_digests(models: Path = MODELS) -> dict[str, str]:
    path = models / "SHA256SUMS"
    lines = path.read_text().splitlines() if path.is_file() else []
    return {name.strip(): digest for digest, name in (line.split(maxsplit=1) for line in lines if line.strip())}


def check_model(path: Path, folders: list[Path], digests: dict[str, str]) -> ModelCheck:
    if digests.get(path.name) != hashlib.sha256(path.read_bytes()).hexdigest():
        return ModelCheck(path.name, False, "the file is not the one models/SHA256SUMS records "
                                            "(git checkout models/ restores it)")
    meta = read_meta(path)
    recorded = meta.features.get("dataset_options")
    if recorded is None:
        return ModelCheck(path.name, False, "its checkpoint records no dataset options to compare the data with")
    options = DatasetOptions.from_dict(recorded)
    try:
        files, _ = choose_files(folders, options.contents)
    except ValueError as error:  # none of its contents in these folders
        return ModelCheck(path.name, False, str(error))
    if fingerprint(files, options) != meta.data_fingerprint:
        return ModelCheck(path.name, False, f"it learnt from other takes than the {len(files)} of its contents "
                                            "found here")
    return ModelCheck(path.name, True, f"it learnt from exactly these {len(files)} takes")


def check_data(folders: str | list[str], models: Path = MODELS, manifest: Path = MANIFEST
               ) -> tuple[list[FolderCheck], list[ModelCheck]]:
    paths = motion_folders(folders)
    sets = read_manifest(manifest)
    digests = recorded_digests(models)
    return ([check_folder(folder, sets) for folder in paths],
            [check_model(path, paths, digests) for path in sorted(models.glob("*.safetensors"))])


def _listed(names: list[str], shown: int = 5) -> str:
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


def describe(folder_checks: list[FolderCheck], model_checks: list[ModelCheck], sets: dict[str, dict[str, str]]
             ) -> list[str]:
    """The report in plain words, one line a finding."""
    lines = []
    seen = {check.expected_set for check in folder_checks}
    for check in folder_checks:
        if check.expected_set is None:
            lines.append(f"{check.folder}: {check.found} BVH files, none of them a take of the Bandai-Namco data "
                         "the committed models learnt from (any BVH folder works; models trained on it apply)")
            continue
        head = f"{check.folder} holds {check.expected_set} ({check.expected} takes expected, {check.found} found)"
        if check.as_expected:
            lines.append(f"{head}: every take as expected")
            continue
        details = [f"{len(check.missing)} missing ({_listed(check.missing)})" if check.missing else "",
                   f"{len(check.changed)} differ in their BVH or labels ({_listed(check.changed)})" if check.changed else "",
                   f"{len(check.unexpected)} not expected ({_listed(check.unexpected)})" if check.unexpected else ""]
        lines.append(f"{head}: " + "; ".join(d for d in details if d))
    for absent in sorted(sets.keys() - seen):
        lines.append(f"{absent}: not among the folders given ({len([n for n in sets[absent] if n.endswith('.bvh')])} "
                     "takes expected)")
    for model in model_checks:
        lines.append(f"models/{model.file}: {'applies' if model.applies else 'does not apply'}: {model.why}")
    if model_checks and all(model.applies for model in model_checks):
        lines.append("So make demo uses the committed models and trains nothing.")
    elif model_checks:
        lines.append("So make demo stops and names the models that do not apply: DEMO_TRAIN=1 make demo trains its "
                     "own on this data (minutes for RNN, VAE and BAD, about an hour for MoGlow), or get the takes "
                     "listed above (docs/data.md).")
    return lines
