"""Registering a study's systems: uploaded checkpoints, natural motion (NAT) and BAD videos.

Uploads are never trusted: a checkpoint must be a safetensors file of this project that
loads completely (digest, kind, every tensor's name and shape), can drive the Generator
and learnt from the data the study's other checkpoints learnt from, prepared the same
way (``data_match``); a video must be an MP4 whose every frame decodes, as long as it
says it lasts (a file cut short still decodes its first frames). Nothing is unpickled or
executed, and a refused upload leaves nothing on disk. Accepted checkpoints are kept by
the project's one checkpoint store (``generation.store.keep``) under ``CHECKPOINT_ROOT``,
named by their content digest, so the same checkpoint uploaded twice is stored once; what
a kind is controlled by and its named presets come from the model registry
(``generation.registry``). Accepted videos become finished stimuli under
``MEDIA_ROOT/stimuli/``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import subprocess
import tempfile
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import imageio_ffmpeg
from django.conf import settings
from django.core.files import File
from django.db import transaction

from generation import registry
from generation.files import atomic_output
from generation.render.video_check import VideoError, read_stream
from generation.store import SUFFIX as CHECKPOINT_SUFFIX
from studyapp.bounds import check_field
from studyapp.models import Stimulus, Study, System, new_token
from studyapp.server.media_bucket import CLIPS_FOLDER, clip_destination
from studyapp.server.uploads.null_characters import null_character_in
from studyapp.stimuli.data_match import data_mismatch

if TYPE_CHECKING:  # torch-backed modules load only when a checkpoint is handled
    from generation.checkpoint import CheckpointMeta

VIDEO_SUFFIX = ".mp4"


class UploadRefused(ValueError):
    """An upload that cannot become a system; the message says what is wrong with it."""


@dataclass(frozen=True)
class StoredCheckpoint:
    relative_path: str  # under CHECKPOINT_ROOT
    digest: str  # its content digest (generation.store.content_digest)
    meta: CheckpointMeta
    parameters: int


def _check_upload(upload: File, suffix: str, limit: int, what: str) -> None:
    name = Path(upload.name or "").name
    if not name.lower().endswith(suffix):
        raise UploadRefused(f"{name or 'the file'}: a {what} must be a {suffix} file")
    if upload.size > limit:
        raise UploadRefused(f"{name}: {upload.size / 1e6:.1f} MB is over the {limit / 1e6:.0f} MB limit for a {what}")


def _copy(upload: File, target: Path) -> str:
    """Write the upload to ``target``; its SHA-256."""
    digest = hashlib.sha256()
    with target.open("wb") as out:
        for chunk in upload.chunks():
            digest.update(chunk)
            out.write(chunk)
    return digest.hexdigest()


def preset_name(meta: CheckpointMeta) -> str:
    """The kind's named presets (the registry's) whose configuration the checkpoint has
    ("paper/cpu" where they are the same), or "custom"."""
    # With the defaults of options newer than the checkpoint filled in, as loading does.
    hyperparameters = dataclasses.asdict(registry.model_class(meta.kind).Config(**meta.hyperparameters))
    matches = [name for name in registry.MODELS[meta.kind].presets
               if dataclasses.asdict(registry.preset(meta.kind, name)) == hyperparameters]
    return "/".join(matches) or "custom"


def checked_checkpoint(path: Path, name: str) -> tuple[CheckpointMeta, int]:
    """The description and parameter count of the checkpoint at ``path`` if it loads
    completely and can drive sampling (UploadRefused naming the file ``name`` if not)."""
    from generation.checkpoint import CheckpointError, load_checkpoint
    from generation.generator import Generator

    try:
        model, meta = load_checkpoint(path)
    except CheckpointError as error:
        raise UploadRefused(f"{name}: {str(error).removeprefix(f'{path}: ')}") from None
    try:
        Generator(model, meta)  # the features and statistics sampling needs are there
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise UploadRefused(f"{name}: a {meta.kind} checkpoint that cannot drive sampling ({error!r})") from None
    if (where := null_character_in(dataclasses.asdict(meta))) is not None:  # PostgreSQL could not store it
        raise UploadRefused(f"{name}: the checkpoint's description holds a NUL character (\\0) in {where}")
    return meta, sum(p.numel() for p in model.parameters())


def store_checkpoint(upload: File, fits: Callable[[CheckpointMeta], str | None] = lambda meta: None) -> StoredCheckpoint:
    """Validate an uploaded checkpoint completely and keep it in the checkpoint store
    (UploadRefused if not); ``fits`` says why a valid checkpoint does not fit where it goes
    (None: it fits), before anything is kept."""
    from generation.store import keep

    _check_upload(upload, CHECKPOINT_SUFFIX, settings.MAX_CHECKPOINT_UPLOAD_BYTES, "checkpoint")
    name = Path(upload.name).name
    root = Path(settings.CHECKPOINT_ROOT)
    root.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=root, prefix=".upload-") as scratch:  # gone whatever happens
        received = Path(scratch) / f"upload{CHECKPOINT_SUFFIX}"
        _copy(upload, received)
        meta, parameters = checked_checkpoint(received, name)
        if (problem := fits(meta)) is not None:
            raise UploadRefused(f"{name}: {problem}")
        stored, digest = keep(received, root)
    return StoredCheckpoint(stored.name, digest, meta, parameters)


def checkpoint_metadata(stored: StoredCheckpoint, original_name: str) -> dict:
    """What the systems page shows and generation needs about a stored checkpoint."""
    meta = stored.meta
    labelled = registry.MODELS[meta.kind].control == registry.LABELS
    labels = {"actions": meta.hyperparameters["actions"], "styles": meta.hyperparameters["styles"]} if labelled else None
    return {
        "labels": labels,
        "file": original_name,
        "preset": preset_name(meta),
        "step": meta.step,
        "data_fingerprint": meta.data_fingerprint,
        "parameters": stored.parameters,
        "code_version": meta.code_version,
        "val_loss": meta.metrics.get("val_loss"),
        "dataset_options": meta.features["dataset_options"],
    }


def check_name(study: Study, name: str) -> None:
    """UploadRefused unless ``name`` is a new, non-blank system name of the study."""
    if not name.strip():
        raise UploadRefused("a system needs a name")
    if study.systems.filter(name=name).exists():
        raise UploadRefused(f"this study already has a system named {name!r}")


def add_checkpoint_system(study: Study, name: str, upload: File, role: str = System.Role.MODEL,
                          temperature: float = 1.0) -> System:
    """A model system (or a BAD one sampled from a weak checkpoint) from an uploaded checkpoint."""
    if role not in (System.Role.MODEL, System.Role.BAD):
        raise UploadRefused(f"a checkpoint makes a model or a BAD system, not {role!r}")
    if problem := check_field(System, "temperature", temperature):
        raise UploadRefused(problem)
    check_name(study, name)
    stored = store_checkpoint(upload, lambda meta: data_mismatch(
        study, registry.MODELS[meta.kind].control, meta.features["dataset_options"], meta.data_fingerprint))
    twin = study.systems.filter(checkpoint_digest=stored.digest, role=role, temperature=temperature).first()
    if twin is not None:
        raise UploadRefused(f"this checkpoint is already system {twin.name!r} at temperature {temperature:g}")
    # A study without checkpoints may have controls already (for submitted motion and NAT): a model
    # trained at another frame rate could follow none of them.
    fps = stored.meta.features["dataset_options"]["fps"]
    other = [control.name for control in study.controls.all() if abs(control.control["fps"] - fps) > 1e-6]
    if other:
        raise UploadRefused(f"this checkpoint was trained at {fps:g} fps and cannot follow the study's controls at "
                            f"another frame rate ({', '.join(other[:3])}{' ...' if len(other) > 3 else ''}); remove "
                            "them first")
    return System.objects.create(
        study=study, name=name, role=role, checkpoint=stored.relative_path, checkpoint_digest=stored.digest,
        kind=stored.meta.kind, metadata=checkpoint_metadata(stored, Path(upload.name).name), temperature=temperature)


def add_natural_system(study: Study, name: str = "NAT") -> System:
    """The natural-motion system: the held-out clips that held-out controls came from."""
    existing = study.systems.filter(role=System.Role.NATURAL).first()
    if existing is not None:
        raise UploadRefused(f"this study already has its natural system {existing.name!r}")
    check_name(study, name)
    return System.objects.create(study=study, name=name, role=System.Role.NATURAL, kind=System.SourceKind.NATURAL)


def video_duration(path: Path) -> float:
    """Seconds of an MP4 whose every frame decodes, to the end its container declares
    (``video_check.read_stream``: a file cut short still decodes its first frames);
    UploadRefused naming the problem if not."""
    with path.open("rb") as stream:
        head = stream.read(12)
    if head[4:8] != b"ftyp":
        raise UploadRefused("not an MP4 file (it has no ftyp box)")
    try:
        decoded = read_stream(path)
    except VideoError as error:
        raise UploadRefused(f"its video does not decode to its end: {str(error).removeprefix(f'{path}: ')}") from None
    if decoded.declared_seconds is None:
        raise UploadRefused("the video does not say how long it lasts")
    return decoded.seconds


def strip_metadata(source: Path, target: Path) -> None:
    """Copy the first video stream of an MP4 into ``target`` without its container's
    metadata (titles, encoder, creation times) or other streams, so a served BAD video
    says nothing about where it came from. The frames are copied, not re-encoded."""
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-y", "-i", str(source), "-map", "0:v:0", "-c", "copy",
               "-map_metadata", "-1", "-map_chapters", "-1", "-fflags", "+bitexact", "-movflags", "+faststart",
               "-f", "mp4", str(target)]
    completed = subprocess.run(command, capture_output=True, text=True, timeout=120)
    if completed.returncode != 0:
        detail = (completed.stderr.strip().splitlines() or ["ffmpeg failed"])[-1]
        raise UploadRefused(f"its video could not be copied ({detail})")


def add_video_system(study: Study, name: str, uploads: list[File], role: str = System.Role.BAD) -> System:
    """A BAD system (or a model rendered elsewhere) whose stimuli are uploaded videos,
    stored as finished stimuli. Such videos do not share the study's camera, renderer or
    size: the systems page says so beside a model system made of them.

    All videos are checked before any is kept: one bad video refuses the whole upload.
    Each is stored with its container metadata removed (``strip_metadata``).
    """
    if role not in (System.Role.MODEL, System.Role.BAD):
        raise UploadRefused(f"videos make a model or a BAD system, not {role!r}")
    if not uploads:
        raise UploadRefused("choose at least one video")
    for upload in uploads:
        _check_upload(upload, VIDEO_SUFFIX, settings.MAX_VIDEO_UPLOAD_BYTES, "video")
    check_name(study, name)
    # Files move into place when the stack closes, just before the rows commit.
    with transaction.atomic(), ExitStack() as stack:
        system = System.objects.create(study=study, name=name, role=role, kind=System.SourceKind.VIDEO,
                                       metadata={"videos": [Path(u.name).name for u in uploads]})
        scratch = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="video-upload-")))
        for upload in uploads:
            token = new_token()
            tmp = stack.enter_context(atomic_output(stack.enter_context(
                clip_destination(f"{CLIPS_FOLDER}/{token}{VIDEO_SUFFIX}"))))
            original = scratch / f"{token}{VIDEO_SUFFIX}"
            digest = _copy(upload, original)
            try:
                video_duration(original)  # an MP4 that decodes, before ffmpeg touches it
                strip_metadata(original, tmp)
                duration = video_duration(tmp)
            except UploadRefused as error:
                raise UploadRefused(f"{Path(upload.name).name}: {error}") from None
            if study.stimuli.filter(content_key=digest).exists():
                raise UploadRefused(f"{Path(upload.name).name}: this video is already a stimulus of the study")
            Stimulus.objects.create(study=study, system=system, control=None, content_key=digest, token=token,
                                    status=Stimulus.Status.DONE, duration_s=duration)
    return system


__all__ = ["UploadRefused", "add_checkpoint_system", "check_name", "checked_checkpoint", "add_natural_system", "add_video_system",
           "store_checkpoint", "video_duration"]
