"""A study written as one bundle (a zip), for another server, a reviewer or a rerun.

    manifest.json           every other file's SHA-256 and size, the format and code versions (``manifest``)
    study.yaml              the study's definition (``studyapp.definitions``), for people and ``create_study --from``
    study.json              the study's settings, systems, controls and questions as records (``records``)
    stimuli.json            its stimuli: system, control, seed, content key, token, duration
    participants.json       its participants (platform ids pseudonymous), their pages and their answers
    ratings.csv, rules.json the ratings table and its rules, as the researcher's export writes them
    plan.json               the plan locked when the study first opened (its SHA-256 and time) and its deviations
    controls/               the controls as export_controls writes them, for labs that submit motion
    checkpoints/DIGEST.safetensors   each checkpoint, named by its content digest as the store keeps it
    motion/DIGEST/ID.npz    each system of submitted motion, as it was stored
    sampled/KEY.npz         the motion sampled for each checkpoint's clip, by the clip's content key
    stimuli/TOKEN.mp4       the videos of uploaded-video systems, and with ``with_videos`` every finished clip

The zip is written to a temporary file beside ``out`` and moved there when complete.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

from django.conf import settings

from generation.checkpoint import code_version
from generation.files import atomic_output
from generation.store import SUFFIX
from studyapp.bundles import records
from studyapp.bundles.manifest import MANIFEST_NAME, VERSION, Entry, Manifest, entry_of, file_entry
from studyapp.definitions import definition_yaml
from studyapp.bundles.pseudonyms import pseudonym, pseudonymous_data
from studyapp.models import Rating, Stimulus, Study, System, json_object
from studyapp.preregistration.lock import preregistration
from studyapp.researchers.results.export import ratings_csv, rules_json
from studyapp.stimuli.clips import CODE_VERSION
from studyapp.stimuli.control_export import bundle_files as control_files
from studyapp.stimuli.sources import sampled_path


class ExportError(ValueError):
    """A study that cannot be written whole (a file it refers to is missing); the message names it."""


def _json(value: object) -> bytes:
    return (json.dumps(value, indent=1, sort_keys=True) + "\n").encode()


def study_record(study: Study) -> dict:
    return {"study": records.record(study),
            "systems": [records.record(system) for system in study.systems.order_by("pk")],
            "controls": [records.record(control) for control in study.controls.order_by("pk")],
            "questions": [records.record(question) for question in study.questions.order_by("pk")]}


def stimuli_record(study: Study, videos: set[int]) -> list[dict]:
    return [{**records.record(stimulus), "system": stimulus.system.name,
             "control": stimulus.control.name if stimulus.control else None,
             "shown_control": stimulus.shown_control.name if stimulus.shown_control else None,
             "video": stimulus.pk in videos}
            for stimulus in study.stimuli.select_related("system", "control", "shown_control").order_by("pk")]


def participants_record(study: Study, key: bytes) -> dict:
    """Participants in the order they came, each with their pages; ratings in the order they
    were stored, which the ratings table's order of equal times follows."""
    tokens = dict(study.stimuli.values_list("pk", "token"))
    participants = []
    for participant in study.participants.prefetch_related("assignments__stimulus").order_by("pk"):
        participants.append({
            **records.record(participant),
            "platform_id": pseudonym(key, participant.platform_id),
            "platform_data": pseudonymous_data(key, json_object(participant, "platform_data")),
            "training": [tokens[pk] for pk in participant.practice_ids() if pk in tokens],
            "assignments": [{**records.record(assignment), "stimulus": assignment.stimulus.token}
                            for assignment in participant.assignments.order_by("position")]})
    ratings = [{**records.record(rating), "assignment": rating.assignment.token}
               for rating in Rating.objects.filter(assignment__participant__study=study)
               .select_related("assignment").order_by("pk")]
    return {"participants": participants, "ratings": ratings}


def _file(path: Path, what: str) -> Path:
    if not path.is_file():
        raise ExportError(f"{what} is missing ({path})")
    return path


def stored_files(study: Study, with_videos: bool) -> tuple[dict[str, Path], set[int]]:
    """The files of the study's systems and clips by their name in the bundle, and the
    stimuli whose videos are among them."""
    files: dict[str, Path] = {}
    for system in study.systems.order_by("pk"):
        if system.checkpoint:
            files[f"{records.CHECKPOINTS}{system.checkpoint_digest}{SUFFIX}"] = _file(
                system.checkpoint_path(), f"the checkpoint of {system.name}")
        elif system.source_kind == System.SourceKind.SUBMITTED:
            folder = Path(settings.CHECKPOINT_ROOT) / json_object(system, "metadata").get("folder", "")
            if not folder.is_dir():
                raise ExportError(f"the submitted motion of {system.name} is missing ({folder})")
            for path in sorted(folder.glob("*.npz")):
                files[f"{records.MOTION}{system.checkpoint_digest}/{path.name}"] = path
    videos = set()
    for stimulus in study.stimuli.select_related("system").order_by("pk"):
        if stimulus.system.checkpoint and sampled_path(stimulus).is_file():
            files[f"{records.SAMPLED}{stimulus.content_key}.npz"] = sampled_path(stimulus)
        uploaded = stimulus.system.source_kind == System.SourceKind.VIDEO
        if stimulus.status == Stimulus.Status.DONE and (uploaded or with_videos):
            what = f"the video of {stimulus.system.name}'s stimulus {stimulus.pk}"
            files[f"{records.VIDEOS}{stimulus.token}.mp4"] = _file(stimulus.video_path(), what)
            videos.add(stimulus.pk)
    return files, videos


def written_files(study: Study, key: bytes, with_videos: bool) -> tuple[dict[str, bytes], dict[str, Path]]:
    """The bundle's files: those made here by name, and those copied from the study's stores."""
    stored, videos = stored_files(study, with_videos)
    made = {records.DEFINITION_FILE: definition_yaml(study).encode(),
            records.STUDY_FILE: _json(study_record(study)),
            records.STIMULI_FILE: _json(stimuli_record(study, videos)),
            records.PARTICIPANTS_FILE: _json(participants_record(study, key)),
            records.RATINGS_FILE: ratings_csv(study),
            records.RULES_FILE: rules_json(study).encode(),
            records.PLAN_FILE: _json(preregistration(study))}
    if study.controls.exists():
        made.update({f"{records.CONTROLS}{name}": data for name, data in control_files(study).items()})
    return made, stored


def write_study_bundle(study: Study, out: Path, key: bytes, with_videos: bool = False) -> Manifest:
    """Write ``study`` as a bundle to ``out`` (ExportError if a file it needs is missing)."""
    made, stored = written_files(study, key, with_videos)
    entries: dict[str, Entry] = {}
    with atomic_output(out) as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in made.items():
            archive.writestr(name, data)
            entries[name] = entry_of(data)
        for name, path in stored.items():  # videos and checkpoints gain nothing from deflating
            archive.write(path, name, zipfile.ZIP_STORED if name.startswith(records.VIDEOS) else zipfile.ZIP_DEFLATED)
            entries[name] = file_entry(path)
        manifest = Manifest(VERSION, code_version(), CODE_VERSION, entries)
        archive.writestr(MANIFEST_NAME, manifest.to_json())
    return manifest


__all__ = ["ExportError", "write_study_bundle"]
