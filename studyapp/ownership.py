"""What a name in a researcher's definition, bundle or form may point at on the server.

A study definition names checkpoints and submitted motion by their digest and motion
folders by their path; a bundle's records and the admin's control form name a held-out
take and its folders (``check_take``). ``owned`` resolves every such name, in one place,
inside the researcher's own space or a space every researcher shares read-only, and
refuses it otherwise:

- a **checkpoint**: one a system of the researcher's studies was made of (uploaded on a
  systems page, or carried in a bundle they imported), or one of the shared checkpoints
  (``SHARED_CHECKPOINTS``: the project's committed models);
- **submitted motion**: motion a system of the researcher's studies was made of;
- a **motion folder**: one of the motion data folders (``MOTION_DATA``) or a folder inside
  one, or a folder the researcher's own held-out controls were found in (added with
  ``add_controls --folder`` by whoever runs the server), or a folder inside that.

The checkpoint store and the folder of submitted motion are shared by every researcher
(files are kept once by their content), so being in the store proves nothing. A refusal
reads the same whether the thing exists, belongs to another researcher or is not there
at all, and names none of the server's folders.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from django.conf import settings
from django.contrib.auth.base_user import AbstractBaseUser

from generation.motion.clip_files import motion_folders
from generation.store import SUFFIX as CHECKPOINT_SUFFIX, CheckpointError, content_digest, read_header
from studyapp.models import ControlSignal, System
from studyapp.stimuli.natural import is_take_name
from studyapp.stimuli.submissions import SUBMITTED_FOLDER

CHECKPOINT, SUBMITTED_MOTION, MOTION_FOLDER = "checkpoint", "submitted motion", "motion folder"


class NotYours(ValueError):
    """A name that points at nothing the researcher may use; the message says so and nothing more."""


def shared_checkpoints() -> dict[str, Path]:
    """The checkpoints every researcher may name, read-only, by their content digest."""
    folder = Path(settings.SHARED_CHECKPOINTS)
    shared = {}
    for path in sorted(folder.glob(f"*{CHECKPOINT_SUFFIX}")) if folder.is_dir() else []:
        try:
            shared[content_digest(read_header(path))] = path
        except CheckpointError:  # not a checkpoint: nothing anyone can name
            continue
    return shared


def _checkpoint(owner: AbstractBaseUser, digest: str) -> Path | None:
    stored = Path(settings.CHECKPOINT_ROOT) / f"{digest}{CHECKPOINT_SUFFIX}"
    if System.objects.filter(study__owner=owner, checkpoint_digest=digest).exclude(checkpoint="").exists() \
            and stored.is_file():
        return stored
    return shared_checkpoints().get(digest)


def _submitted_motion(owner: AbstractBaseUser, digest: str) -> Path | None:
    stored = Path(settings.CHECKPOINT_ROOT) / SUBMITTED_FOLDER / digest
    own = System.objects.filter(study__owner=owner, kind=System.SourceKind.SUBMITTED, checkpoint_digest=digest)
    return stored if own.exists() and stored.is_dir() else None


def _recorded_folders(owner: AbstractBaseUser) -> list[str]:
    """The folders the owner's held-out controls were found in."""
    folders = []
    for natural in ControlSignal.objects.filter(study__owner=owner, origin=ControlSignal.Origin.HELD_OUT) \
            .values_list("natural", flat=True):
        recorded = natural.get("folders") if isinstance(natural, dict) else None
        folders += [folder for folder in recorded if isinstance(folder, str)] if isinstance(recorded, list) else []
    return folders


def _resolved(path: Path) -> Path | None:
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError):  # a loop of links, a NUL character: no folder of anyone's
        return None


def _folders(names: str) -> list[Path]:
    """The folders ``names`` gives, several joined with ":" as MOTION_DATA joins them (none for none)."""
    try:
        return motion_folders(names)
    except FileNotFoundError:
        return []


def _motion_folder(owner: AbstractBaseUser, name: str) -> Path | None:
    parts = _folders(name)
    folders = [_resolved(part) if part.is_absolute() else None for part in parts]
    shared = _folders(str(settings.MOTION_DATA))
    roots = [_resolved(root) for root in [*shared, *map(Path, dict.fromkeys(_recorded_folders(owner)))]]
    usable = bool(folders) and all(folder is not None and any(root is not None and folder.is_relative_to(root)
                                                              for root in roots) for folder in folders)
    return Path(name) if usable else None


RESOLVERS: dict[str, Callable[[AbstractBaseUser, str], Path | None]] = {
    CHECKPOINT: _checkpoint, SUBMITTED_MOTION: _submitted_motion, MOTION_FOLDER: _motion_folder}
REFUSALS = {
    CHECKPOINT: "no checkpoint {name} in the checkpoint store that is yours or shared: upload its file on a systems "
                "page of one of your studies first",
    SUBMITTED_MOTION: "no submitted motion {name} that is yours: upload it on a systems page of one of your studies "
                      "first",
    MOTION_FOLDER: "{name!r} is not a motion folder you may use: name one of the motion data folders (MOTION_DATA) "
                   "or a folder inside one, or a folder your own held-out controls were found in",
}


def owned(owner: AbstractBaseUser, kind: str, name: str) -> Path:
    """Where the ``kind`` (CHECKPOINT, SUBMITTED_MOTION, MOTION_FOLDER: one, or several
    joined with ":") that ``name`` names lies, if ``owner`` may use it; NotYours otherwise,
    in words that tell nothing of whether it exists."""
    path = RESOLVERS[kind](owner, name)
    if path is None:
        raise NotYours(REFUSALS[kind].format(name=name[:200]))
    return path


def check_take(owner: AbstractBaseUser, source_clip: str, natural: object) -> None:
    """A held-out control's record of where its take is (NAT and the controls' download read
    it): ``source_clip`` a file inside its folders, and each folder ``natural`` records one
    ``owner`` may name; NotYours otherwise."""
    if source_clip and not is_take_name(source_clip):
        raise NotYours(f"its take {source_clip[:80]!r} is no file inside a motion folder")
    folders = natural.get("folders", []) if isinstance(natural, dict) else []
    if not isinstance(folders, list) or not all(isinstance(folder, str) for folder in folders):
        raise NotYours("its natural record's folders are no list of paths")
    for folder in folders:
        owned(owner, MOTION_FOLDER, folder)


__all__ = ["CHECKPOINT", "MOTION_FOLDER", "NotYours", "SUBMITTED_MOTION", "check_take", "owned", "shared_checkpoints"]
