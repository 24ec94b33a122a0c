"""Submitted motion: another lab's clips for the study's controls, as a system.

A submission is a folder or a zip of motion files as the lab has them: one BVH (any
unit, y or z up, starting anywhere) or ``.npz`` per control, named by the control's id
(``control_export.control_id``) or ``ID_NN.bvh`` as ``sample`` names its clips. The files
go through ``generation.submission.prepare_submission`` with the study's own controls,
in one pass, exactly as ``python -m generation prepare-submission`` runs it: the unit
and up axis detected (or given), each clip resampled and cut to its control, moved on
the floor so its root starts at the control's start (unless kept where it is), and
refused where a control has no usable clip. Its report says per control what was
matched, converted and refused; a refused submission is refused whole with the report
(``SubmissionRefused``), and an accepted one keeps it in the system's metadata. Accepted
clips are reduced to the body (the hips and below, as NAT clips are) and stored as
``.npz`` under ``CHECKPOINT_ROOT/submitted/<digest>/``; ``sources.SubmittedMotion``
reads them and the workers render them as they render sampled motion.

A zip is read member by member into memory by ``studyapp.server.uploads.zips``, never
extracted: no member name becomes a path (no zip slip), and no member is read past its
declared size or the upload cap (no zip bomb).
"""

from __future__ import annotations

import hashlib
import io
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from django.conf import settings
from django.core.files import File

from generation.motion.kinematics import subtree_motion
from generation.motion.npz import load_motion_npz, save_motion_npz
from generation.motion.root import RootOptions, hips_index
from generation.motion.types import Motion
from generation.render.display_figure import MappingError, complete_mapping, mapping_pose
from generation.submission import MOTION_SUFFIXES, prepare_submission
from studyapp.models import ControlSignal, Study, System
from studyapp.server.uploads.zips import ZipRefused, checked_members, copy_member, opened_zip
from studyapp.stimuli.control_export import control_id
from studyapp.stimuli.controls import ControlError, study_options
from studyapp.stimuli.systems import UploadRefused, check_name

SUBMITTED_FOLDER = "submitted"


class SubmissionRefused(UploadRefused):
    """Submitted motion that cannot become a system; ``lines`` say why: the report of
    every control where the files were read. ``refused``: those of the lines that say what
    was refused (every line unless told), apart from those that say what would be kept."""

    def __init__(self, lines: list[str], refused: list[str] | None = None) -> None:
        self.lines = lines
        self.refused = lines if refused is None else refused
        super().__init__("the submitted motion was not registered:\n" + "\n".join(f"- {line}" for line in lines))


@dataclass(frozen=True)
class Reading:
    """How the submitted files are read: the BVH files' unit (``scale``, file units to cm)
    and up axis, None where detected, and whether each clip stays where it is on the
    floor (``keep_root``) instead of starting at its control's start."""

    scale: float | None = None
    up: str | None = None
    keep_root: bool = False


def _max_bytes() -> int:
    return settings.MAX_MOTION_UPLOAD_BYTES


def read_zip(stream) -> dict[str, bytes]:
    """The motion files of a zip by file name (folders inside it ignored), read as
    ``studyapp.server.uploads.zips`` reads any zip from outside; UploadRefused naming the member
    where it cannot be read."""
    limit = _max_bytes()
    files = {}
    try:
        with opened_zip(stream) as archive:
            for info in checked_members(archive, limit):
                buffer = io.BytesIO()
                copy_member(archive, info, buffer, limit)
                files[info.filename] = buffer.getvalue()
    except ZipRefused as error:
        raise UploadRefused(str(error)) from None
    return files


def read_folder(folder: Path) -> dict[str, bytes]:
    """The files of a folder (and its subfolders) by path relative to it."""
    limit, total, files = _max_bytes(), 0, {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        total += path.stat().st_size
        if total > limit:
            raise UploadRefused(f"{folder}: over the {limit / 1e6:g} MB limit for submitted motion")
        files[str(path.relative_to(folder))] = path.read_bytes()
    return files


@dataclass(frozen=True)
class Accepted:
    control: ControlSignal
    motion: Motion
    source_fps: float  # the rate of the file it came from


def _motion_files(files: dict[str, bytes]) -> dict[str, str]:
    """The motion files' paths by file name (README files, macOS resource forks and the
    like left out); SubmissionRefused where two share a name, since only the name counts."""
    named: dict[str, list[str]] = {}
    for path in files:
        name = PurePosixPath(path).name
        if not (name.startswith(".") or path.startswith("__MACOSX/") or Path(name).suffix.lower() not in MOTION_SUFFIXES):
            named.setdefault(name, []).append(path)
    shared = [" and ".join(paths) for paths in named.values() if len(paths) > 1]
    if shared:
        raise SubmissionRefused([f"{paths}: only a file's name counts, and these have the same" for paths in shared])
    return {name: paths[0] for name, paths in named.items()}


def check_submission(study: Study, files: dict[str, bytes], reading: Reading = Reading()
                     ) -> tuple[list[Accepted], list[str]]:
    """Every control's accepted motion and the report of what became of each file (its
    lines); SubmissionRefused with the report where a control has no usable clip."""
    try:
        root = study_options(study).root
    except ControlError as error:
        raise SubmissionRefused([str(error)]) from None
    by_id = {control_id(c): c for c in study.controls.all()}
    if not by_id:
        raise SubmissionRefused(["the study has no controls yet: add them, export them, then submit motion"])
    named = _motion_files(files)
    controls = {ident: control.signal() for ident, control in by_id.items()}
    with tempfile.TemporaryDirectory() as scratch:
        # prepare_submission reads files: each keeps its name, nothing else of its path.
        paths = [Path(scratch) / name for name in named]
        for path in paths:
            try:
                path.write_bytes(files[named[path.name]])
            except OSError as error:  # a name this file system does not take
                raise SubmissionRefused([f"{named[path.name]}: not a usable file name ({error.strerror})"]) from None
        try:
            report = prepare_submission(paths, controls, reading.scale, reading.up, root, not reading.keep_root,
                                        study.path_tolerance_cm)
        except ValueError as error:  # BVH files that mix units
            raise SubmissionRefused([str(error).replace(f"{scratch}{os.sep}", "")]) from None
        lines = [line.replace(f"{scratch}{os.sep}", "") for line in report.lines()]
        refused = [line.replace(f"{scratch}{os.sep}", "") for line in report.refused_lines()]
    if not report.accepted:
        raise SubmissionRefused(lines, refused)
    return [Accepted(by_id[result.control], _body(result.motion, root), result.source_fps)
            for result in report.results], lines


def _body(motion: Motion, root: RootOptions) -> Motion:
    """The body (the hips and below), as NAT clips and the models' data are."""
    return subtree_motion(motion, hips_index(motion.skeleton, root.hips))


def stored_motion_digest(folder: Path) -> str:
    """The digest that names a folder of stored clips: of each control id and its file's
    bytes, in the order of the ids (the folder's name in the store)."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.npz"), key=lambda p: p.stem):
        digest.update(path.stem.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _store(accepted: list[Accepted]) -> tuple[str, str]:
    """Write the accepted clips under CHECKPOINT_ROOT; (folder relative to it, digest)."""
    root = Path(settings.CHECKPOINT_ROOT) / SUBMITTED_FOLDER
    root.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(dir=root, prefix=".upload-"))
    try:
        for item in accepted:
            save_motion_npz(item.motion, scratch / f"{control_id(item.control)}.npz")
        final = root / stored_motion_digest(scratch)
        if not final.exists():  # the same motion submitted twice is stored once
            os.chmod(scratch, 0o755)
            os.replace(scratch, final)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return f"{SUBMITTED_FOLDER}/{final.name}", final.name


def add_submitted_system(study: Study, name: str, files: dict[str, bytes], role: str = System.Role.MODEL,
                         source: str = "", reading: Reading = Reading(),
                         figure_mapping: dict[str, str] | None = None) -> System:
    """A system of submitted motion (``files`` by name, from ``read_zip`` or ``read_folder``);
    its metadata keeps the report of what became of each file. Its rig must map to every
    point of the display figure (``figure_mapping`` corrects what is found): refused
    naming the points it lacks."""
    if role not in (System.Role.MODEL, System.Role.BAD):
        raise UploadRefused(f"submitted motion makes a model or a BAD system, not {role!r}")
    check_name(study, name)
    accepted, report = check_submission(study, files, reading)
    first = accepted[0].motion
    try:
        complete_mapping(first.skeleton, mapping_pose(first), figure_mapping)
    except MappingError as error:
        raise UploadRefused(f"its rig cannot be drawn on the study's display figure: {error}") from None
    folder, digest = _store(accepted)
    twin = study.systems.filter(kind=System.SourceKind.SUBMITTED, checkpoint_digest=digest).first()
    if twin is not None:
        raise UploadRefused(f"this motion is already system {twin.name!r}")
    skeleton = accepted[0].motion.skeleton
    return System.objects.create(
        study=study, name=name, role=role, kind=System.SourceKind.SUBMITTED, checkpoint_digest=digest,
        figure_mapping=figure_mapping or {},
        metadata={"folder": folder, "controls": sorted(a.control.name for a in accepted), "file": source,
                  "joints": skeleton.n_joints, "report": report,
                  "fps": sorted({item.source_fps for item in accepted})})  # as submitted, for the readiness check


def add_submitted_upload(study: Study, name: str, upload: File, role: str = System.Role.MODEL,
                         reading: Reading = Reading()) -> System:
    """A system from an uploaded zip of motion (the systems page, ``add_system --motion``)."""
    original = Path(upload.name or "").name
    if not original.lower().endswith(".zip"):
        raise UploadRefused(f"{original or 'the file'}: submitted motion must be a .zip")
    if upload.size > _max_bytes():
        raise UploadRefused(f"{original}: {upload.size / 1e6:.1f} MB is over the {_max_bytes() / 1e6:g} MB limit")
    upload.seek(0)
    return add_submitted_system(study, name, read_zip(upload), role, original, reading)


def read_stored_motion(system: System, control: ControlSignal) -> Motion:
    """The stored clip of a submitted-motion system for a control."""
    path = Path(settings.CHECKPOINT_ROOT) / system.metadata["folder"] / f"{control_id(control)}.npz"
    if not path.is_file():
        raise FileNotFoundError(f"the submitted motion of {system.name} for {control.name} is missing ({path})")
    return load_motion_npz(path)


__all__ = ["Reading", "SubmissionRefused", "add_submitted_system", "add_submitted_upload", "check_submission",
           "read_folder", "read_stored_motion", "read_zip", "stored_motion_digest"]
