"""Submitted motion: another lab's clips for the study's exported controls, as a system.

A submission is a folder or a zip holding one BVH or ``.npz`` per control, named by the
control's id (``control_export.control_id``; the bundle's README.txt states the rules).
Everything is checked before anything is stored and every problem is listed at once
(``SubmissionRefused``): controls without a file and files of no control, skeletons that
differ, unreadable or non-finite motion, a frame rate below the control's, a clip
shorter than its control, lengths that are not centimetres, and a root that strays from
the commanded path. Accepted clips are reduced to the body (the hips and below, as NAT
clips are), resampled to the control's frame rate, trimmed to its frames and stored as
``.npz`` under ``CHECKPOINT_ROOT/submitted/<digest>/``; ``sources.SubmittedMotion``
reads them and the workers render them as they render sampled motion.

A zip is read member by member into memory, never extracted: no member name becomes a
path (no zip slip), and no member is read past its declared size or the upload cap (no
zip bomb).
"""

from __future__ import annotations

import hashlib
import io
import os
import shutil
import struct
import tempfile
import zipfile
import zlib
from collections import Counter
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
from django.conf import settings
from django.core.files import File

from generation.control import PathControl
from generation.motion.bvh import BVHError, load_motion
from generation.motion.kinematics import subtree_motion
from generation.motion.npz import load_motion_npz, save_motion_npz
from generation.motion.resample import resample
from generation.motion.root import hips_index, root_trajectory
from generation.motion.types import Motion
from studyapp.models import ControlSignal, Study, System
from studyapp.stimuli.control_export import MAX_HEIGHT_CM, MIN_HEIGHT_CM, PATH_TOLERANCE_CM, control_id
from studyapp.stimuli.controls import ControlError, training_options
from studyapp.stimuli.systems import UploadRefused, check_name

MOTION_SUFFIXES = (".bvh", ".npz")
MAX_MEMBERS = 10_000
SUBMITTED_FOLDER = "submitted"


class SubmissionRefused(UploadRefused):
    """Submitted motion that cannot become a system; ``problems`` lists every reason."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        super().__init__(f"{len(problems)} problem(s) with the submitted motion:\n" + "\n".join(
            f"- {problem}" for problem in problems))


def _max_bytes() -> int:
    return settings.MAX_MOTION_UPLOAD_BYTES


def read_zip(stream) -> dict[str, bytes]:
    """The motion files of a zip by file name (folders inside it ignored).

    A damaged archive fails in many ways inside zipfile (a CRC that does not match, a
    member that inflates past its declared size, a cut deflate stream, a compression
    method it lacks, headers that contradict each other); each is refused naming the
    member.
    """
    limit = _max_bytes()
    damaged = (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, OSError, ValueError, struct.error)
    try:
        archive = zipfile.ZipFile(stream)
    except damaged as error:
        raise UploadRefused(f"not a zip file ({error})") from None
    with archive:
        members = [info for info in archive.infolist() if not info.is_dir()]
        if len(members) > MAX_MEMBERS:
            raise UploadRefused(f"the zip holds {len(members)} files; at most {MAX_MEMBERS}")
        declared = sum(info.file_size for info in members)
        if declared > limit:
            raise UploadRefused(f"the zip unpacks to {declared / 1e6:.3g} MB, over the {limit / 1e6:g} MB limit")
        files = {}
        for info in members:
            if info.flag_bits & 0x1:
                raise UploadRefused(f"{info.filename}: encrypted zip members are not read")
            try:
                with archive.open(info) as member:
                    data = member.read(info.file_size + 1)  # never past what the directory declares
            except damaged as error:
                raise UploadRefused(f"{info.filename}: a damaged zip member ({error})") from None
            if len(data) > info.file_size:
                raise UploadRefused(f"{info.filename}: unpacks to more than its declared {info.file_size} bytes")
            files[info.filename] = data
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


def _parse(name: str, data: bytes) -> Motion:
    """A file's motion; ValueError naming the problem."""
    if name.lower().endswith(".npz"):
        return load_motion_npz(io.BytesIO(data))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(data)
        try:
            return load_motion(path)
        except (BVHError, UnicodeDecodeError) as error:
            raise ValueError(str(error).replace(str(path), name)) from None


def body_height(motion: Motion) -> float:
    """The largest vertical extent of the body over the clip (about a person's height when standing)."""
    y = motion.positions[..., 1]
    return float((y.max(axis=1) - y.min(axis=1)).max())


@dataclass(frozen=True)
class Accepted:
    control: ControlSignal
    motion: Motion


def _check_one(name: str, motion: Motion, control: ControlSignal, root_options) -> tuple[Motion | None, list[str]]:
    """The motion as the study will render it (body, control's fps and frames), or the problems."""
    signal = control.signal()
    problems = []
    if motion.fps + 1e-6 < signal.fps:
        return None, [f"{name}: {motion.fps:g} fps is below the control's {signal.fps:g} fps; "
                      "motion is resampled down, never up"]
    body = resample(subtree_motion(motion, hips_index(motion.skeleton, root_options.hips)), signal.fps)
    if body.n_frames < signal.n_frames:
        return None, [f"{name}: {body.n_frames} frames ({body.n_frames / signal.fps:.2f} s) at {signal.fps:g} fps, "
                      f"shorter than its control's {signal.n_frames} frames ({signal.n_frames / signal.fps:.2f} s)"]
    body = Motion(body.positions[:signal.n_frames], body.fps, body.skeleton)
    height = body_height(body)
    if not MIN_HEIGHT_CM <= height <= MAX_HEIGHT_CM:
        problems.append(f"{name}: the body is {height:.3g} units tall; lengths must be centimetres "
                        f"(a body {MIN_HEIGHT_CM:g}-{MAX_HEIGHT_CM:g} cm tall)")
    elif isinstance(signal, PathControl):
        try:
            root = root_trajectory(body, root_options).xz
        except ValueError as error:
            return None, [f"{name}: {error}"]
        distance = np.linalg.norm(root - signal.path().xz, axis=1)
        worst = int(distance.argmax())
        if distance[worst] > PATH_TOLERANCE_CM:
            problems.append(f"{name}: the root strays {distance[worst]:.0f} cm from the control's path (at frame "
                            f"{worst}); the tolerance is {PATH_TOLERANCE_CM:g} cm")
    return (None if problems else body), problems


def check_submission(study: Study, files: dict[str, bytes]) -> list[Accepted]:
    """Every control's accepted motion; SubmissionRefused listing every problem if any."""
    try:
        root_options = training_options(study).root
    except ControlError as error:
        raise SubmissionRefused([str(error)]) from None
    by_id = {control_id(c): c for c in study.controls.all()}
    if not by_id:
        raise SubmissionRefused(["the study has no controls yet: add them, export them, then submit motion"])
    problems: list[str] = []
    chosen: dict[str, str] = {}
    for path in files:
        name = PurePosixPath(path).name
        stem, suffix = os.path.splitext(name)
        if name.startswith(".") or path.startswith("__MACOSX/") or suffix.lower() not in MOTION_SUFFIXES:
            continue  # README files, macOS resource forks and the like
        if stem not in by_id:
            problems.append(f"{path}: no control has the id {stem!r}")
        elif stem in chosen:
            problems.append(f"{path}: control {stem!r} already has the file {chosen[stem]}")
        else:
            chosen[stem] = path
    missing = sorted(set(by_id) - set(chosen))
    if missing:
        problems.append(f"no file for the control(s) {', '.join(missing)}")
    motions = {}
    for stem, path in sorted(chosen.items()):
        try:
            motions[stem] = _parse(PurePosixPath(path).name, files[path])
        except ValueError as error:
            problems.append(f"{path}: {error}")
    # The skeleton most files share is the submission's; the others are listed against it.
    skeletons = {stem: (m.skeleton.names, tuple(m.skeleton.parents)) for stem, m in motions.items()}
    common = Counter(skeletons.values()).most_common(1)
    accepted = []
    for stem, motion in motions.items():
        path = chosen[stem]
        if skeletons[stem] != common[0][0]:
            sharing = [chosen[s] for s, k in skeletons.items() if k == common[0][0]]
            problems.append(f"{path}: its skeleton ({motion.skeleton.n_joints} joints) differs from the one of "
                            f"{len(sharing)} other file(s), e.g. {sharing[0]} ({len(common[0][0][0])} joints)")
            continue
        body, found = _check_one(path, motion, by_id[stem], root_options)
        problems += found
        if body is not None:
            accepted.append(Accepted(by_id[stem], body))
    if problems:
        raise SubmissionRefused(problems)
    return accepted


def _store(accepted: list[Accepted]) -> tuple[str, str]:
    """Write the accepted clips under CHECKPOINT_ROOT; (folder relative to it, digest)."""
    root = Path(settings.CHECKPOINT_ROOT) / SUBMITTED_FOLDER
    root.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(dir=root, prefix=".upload-"))
    try:
        digest = hashlib.sha256()
        for item in sorted(accepted, key=lambda a: control_id(a.control)):
            path = save_motion_npz(item.motion, scratch / f"{control_id(item.control)}.npz")
            digest.update(control_id(item.control).encode() + b"\0" + path.read_bytes())
        final = root / digest.hexdigest()
        if not final.exists():  # the same motion submitted twice is stored once
            os.chmod(scratch, 0o755)
            os.replace(scratch, final)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return f"{SUBMITTED_FOLDER}/{final.name}", final.name


def add_submitted_system(study: Study, name: str, files: dict[str, bytes], role: str = System.Role.MODEL,
                         source: str = "") -> System:
    """A system of submitted motion (``files`` by name, from ``read_zip`` or ``read_folder``)."""
    if role not in (System.Role.MODEL, System.Role.BAD):
        raise UploadRefused(f"submitted motion makes a model or a BAD system, not {role!r}")
    check_name(study, name)
    accepted = check_submission(study, files)
    folder, digest = _store(accepted)
    twin = study.systems.filter(kind=System.SourceKind.SUBMITTED, checkpoint_digest=digest).first()
    if twin is not None:
        raise UploadRefused(f"this motion is already system {twin.name!r}")
    skeleton = accepted[0].motion.skeleton
    return System.objects.create(
        study=study, name=name, role=role, kind=System.SourceKind.SUBMITTED, checkpoint_digest=digest,
        metadata={"folder": folder, "controls": sorted(a.control.name for a in accepted), "file": source,
                  "joints": skeleton.n_joints})


def add_submitted_upload(study: Study, name: str, upload: File, role: str = System.Role.MODEL) -> System:
    """A system from an uploaded zip of motion (the systems page, ``add_system --motion``)."""
    original = Path(upload.name or "").name
    if not original.lower().endswith(".zip"):
        raise UploadRefused(f"{original or 'the file'}: submitted motion must be a .zip")
    if upload.size > _max_bytes():
        raise UploadRefused(f"{original}: {upload.size / 1e6:.1f} MB is over the {_max_bytes() / 1e6:g} MB limit")
    upload.seek(0)
    return add_submitted_system(study, name, read_zip(upload), role, original)


def read_stored_motion(system: System, control: ControlSignal) -> Motion:
    """The stored clip of a submitted-motion system for a control."""
    path = Path(settings.CHECKPOINT_ROOT) / system.metadata["folder"] / f"{control_id(control)}.npz"
    if not path.is_file():
        raise FileNotFoundError(f"the submitted motion of {system.name} for {control.name} is missing ({path})")
    return load_motion_npz(path)


__all__ = ["SubmissionRefused", "add_submitted_system", "add_submitted_upload", "body_height", "check_submission",
           "read_folder", "read_stored_motion", "read_zip"]
