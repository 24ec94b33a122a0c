"""A read bundle re-created as a new study: all of it, or nothing.

The study's settings, systems, controls and questions are made from the bundle's
records, which hold every value exactly (the control arrays among them), and its
definition (``study.yaml``) must be read as a definition and describe the study made:
a bundle whose two descriptions disagree is refused at the first line that differs.

Every row is made in one transaction, each checked as the pages check it
(``full_clean``); every file (checkpoints, submitted motion, sampled motion, videos) is
checked as an upload of its kind is, written under a temporary name beside its place
and moved there only when every row is made, just before the transaction commits. Any
problem refuses the bundle with ``BundleRefused`` naming the file and the record, and
leaves no row and no file behind.

The new study has a new key and is closed. Its stimuli keep their seeds, content keys
and, where free in this database, their tokens, as its participants keep their codes:
its ratings table is then the original's, and so is the report computed from it. A
stimulus's content key is computed again here from the imported study, system and
control, and must be the recorded one (the stimulus code being the same version): a
bundle whose clips would not be the ones rated is refused. Clips whose video came in
the bundle are finished; the others wait for ``generate_stimuli`` to render them again,
from the bundle's sampled motion, which is kept under the new study alone
(``sources.imported_sampled_path``): never in the shared folder, where another study's
clip of the same content key would be drawn from it. A held-out control's take must be a
file inside its folders, and each folder one the owner may name (``studyapp.ownership``).

As a rerun (``rerun``), the participants and ratings are not imported: the study is
the same design, systems, controls and clips, for new participants, and the bundle's
ratings table and rules are kept as its previous run (``PreviousRun``), which its
report compares with the new ratings.

The plan locked when the original opened (``plan.json``) comes along with its recorded
deviations, checked against its SHA-256, so the imported study's report states the same
plan; a rerun locks a plan of its own when it opens.
"""

from __future__ import annotations

import re
import shutil
import tempfile
from contextlib import ExitStack
from pathlib import Path
from typing import BinaryIO

from django.conf import settings
from django.core.exceptions import ValidationError
from django.db import transaction

from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import ExclusionRules
from generation.files import atomic_folder, atomic_output
from generation.motion.npz import MotionFileError, load_motion_npz
from generation.store import SHA256_HEX, SUFFIX, CheckpointError, content_digest, read_header
from studyapp import ownership
from studyapp.bundles import records
from studyapp.bundles.manifest import BundleRefused
from studyapp.bundles.reading import ReadBundle, member_limit, read_bundle
from studyapp.definitions import DefinitionError, definition_yaml
from studyapp.definitions.reading import read_definition
from studyapp.models import (Assignment, ControlSignal, Participant, PreviousRun, Question, Rating, Stimulus,
                             StoredDataError, Study, System, new_token)
from studyapp.preregistration.lock import preregistration, restore_preregistration
from studyapp.preregistration.words import plan_markdown
from studyapp.server.uploads.bounded_reading import ReadRefused, json_value, read_bytes, utf8_text
from studyapp.stimuli.clips import CODE_VERSION, content_key
from studyapp.stimuli.sources import imported_sampled_path
from studyapp.stimuli.submissions import SUBMITTED_FOLDER, stored_motion_digest
from studyapp.stimuli.systems import UploadRefused, checked_checkpoint, video_duration

# What names a file (a digest, a stimulus's token) must look like before it becomes part of a path.
TOKEN = re.compile(r"[0-9A-Za-z_-]{1,32}")


def _file_name(value: object, pattern: re.Pattern, what: str, where: str, why: str = "it names a file") -> str:
    if not isinstance(value, str) or not pattern.fullmatch(value):
        raise records.RecordError(f"{where}: its {what} {str(value)[:80]!r} is no {what} ({why})")
    return value


def _id(value: object, what: str, where: str) -> str:
    """A participant's code or a page's token: there, and no longer than its column (a model
    field Django fills itself is not validated by ``full_clean``)."""
    return _file_name(value, TOKEN, what, where, "1 to 32 letters, digits, '-' or '_'")


def _member(bundle: ReadBundle, name: str) -> Path:
    """The bundle's file ``name``, refused when it is missing."""
    path = bundle.path(name)
    if not path.is_file():
        raise BundleRefused(f"{name}: missing from the bundle")
    return path


def _bytes(bundle: ReadBundle, name: str) -> bytes:
    """The file ``name``, within the limit of its kind (``reading.member_limit``, which its unpacking held it to)."""
    return read_bytes(_member(bundle, name), name, member_limit(name))


def _text(bundle: ReadBundle, name: str) -> str:
    return utf8_text(_bytes(bundle, name), name)


def _json(bundle: ReadBundle, name: str) -> object:
    return json_value(_bytes(bundle, name), name, member_limit(name))


def _items(data: object, key: str, where: str) -> list:
    value = data.get(key) if isinstance(data, dict) else None
    if not isinstance(value, list):
        raise records.RecordError(f"{where}: '{key}' must be a list")
    return value


def _pop(data: object, key: str, where: str) -> object:
    if not isinstance(data, dict) or key not in data:
        raise records.RecordError(f"{where}: lacks '{key}'")
    return data.pop(key)


def _saved(row, where: str, stamped: dict | None = None):
    """``row`` checked as the pages check it, and saved; ``stamped`` sets afterwards the
    times Django stamps on saving."""
    try:
        row.clean_fields()  # every field of its type before the model's own checks compare them
        row.full_clean()
    except ValidationError as error:
        problems = "; ".join(f"{field}: {' '.join(messages)}" for field, messages in error.message_dict.items())
        raise records.RecordError(f"{where}: {problems}") from None
    row.save()
    if stamped:
        type(row).objects.filter(pk=row.pk).update(**stamped)
    return row


def _free(model, field: str, value: object) -> object:
    """``value``, or a new token where a row of this database already has it."""
    return new_token() if isinstance(value, str) and model.objects.filter(**{field: value}).exists() else value


def _check_take(control: ControlSignal, owner, where: str) -> None:
    try:
        ownership.check_take(owner, control.source_clip, control.natural)
    except ownership.NotYours as error:
        raise records.RecordError(f"{where}: {error}") from None
def _answer(study: Study, values: dict, where: str) -> dict:
    """A rating's values, refused where the rating pages would refuse the answer: a value
    off the study's scale, a strength of preference the study does not offer."""
    value, strength = values.get("value"), values.get("strength")
    if value is not None and value not in study.scale:
        raise records.RecordError(f"{where}: value {value} is outside the study's scale "
                                  f"{study.scale_min}-{study.scale_max}")
    if strength is not None and strength not in study.strengths:
        raise records.RecordError(f"{where}: strength {strength} is not one of the study's "
                                  f"{study.preference_strengths} degrees of preference")
    return values


class _Import:
    """One bundle's import: the rows made so far by name or token, and the files to place."""

    def __init__(self, bundle: ReadBundle, placing: ExitStack) -> None:
        self.bundle, self.placing = bundle, placing
        self.systems: dict[str, System] = {}
        self.controls: dict[str, ControlSignal] = {}
        self.stimuli: dict[str, Stimulus] = {}
        self.assignments: dict[str, Assignment] = {}

    def place_file(self, source: Path, target: Path) -> None:
        """Copy ``source`` to ``target`` under a temporary name, moved there when the import
        succeeds (a file already there is the same content: checkpoints and motion are
        named by their digest)."""
        if target.exists():
            return
        shutil.copyfile(source, self.placing.enter_context(atomic_output(target)))

    # --- the study and what it is made of ---------------------------------------

    def make_study(self, owner) -> Study:
        data = _json(self.bundle, records.STUDY_FILE)
        where = records.STUDY_FILE
        values = records.row_values(Study, _pop(data, "study", where), f"{where}: study")
        study = _saved(Study(owner=owner, is_open=False, **values), f"{where}: study")
        for index, item in enumerate(_items(data, "controls", where)):
            control = ControlSignal(study=study, **records.row_values(ControlSignal, item, f"{where}: controls[{index}]"))
            _check_take(control, owner, f"{where}: control {control.name!r}")  # before it is one of the owner's
            self.controls[control.name] = _saved(control, f"{where}: control {control.name!r}")
        for index, item in enumerate(_items(data, "systems", where)):
            system = System(study=study, **records.row_values(System, item, f"{where}: systems[{index}]"))
            self.system_files(system)
            self.systems[system.name] = _saved(system, f"{where}: system {system.name!r}")
        for index, item in enumerate(_items(data, "questions", where)):
            _saved(Question(study=study, **records.row_values(Question, item, f"{where}: questions[{index}]")),
                   f"{where}: questions[{index}]")
        return study

    def system_files(self, system: System) -> None:
        """Check and place the files a system's motion comes from."""
        where = f"{records.STUDY_FILE}: system {system.name!r}"
        if not (system.checkpoint or system.source_kind == System.SourceKind.SUBMITTED):
            return
        digest = _file_name(system.checkpoint_digest, SHA256_HEX, "digest", where)
        if system.checkpoint:
            name = f"{digest}{SUFFIX}"
            if system.checkpoint != name:
                raise records.RecordError(f"{where}: its checkpoint must be named by its digest ({name})")
            path = self.bundle.path(f"{records.CHECKPOINTS}{name}")
            if not path.is_file():
                raise BundleRefused(f"{records.CHECKPOINTS}{name}: the checkpoint of {system.name} is missing")
            checked_checkpoint(path, f"{records.CHECKPOINTS}{name}")
            try:
                if content_digest(read_header(path)) != digest:
                    raise BundleRefused(f"{records.CHECKPOINTS}{name}: its content is not that of its digest")
            except CheckpointError as error:
                raise BundleRefused(str(error).replace(str(self.bundle.folder) + "/", "")) from None
            self.place_file(path, Path(settings.CHECKPOINT_ROOT) / name)
        elif system.source_kind == System.SourceKind.SUBMITTED:
            folder = f"{SUBMITTED_FOLDER}/{digest}"
            if not isinstance(system.metadata, dict) or system.metadata.get("folder") != folder:
                raise records.RecordError(f"{where}: its motion must lie in the folder named by its digest ({folder})")
            source = self.bundle.path(f"{records.MOTION}{digest}")
            if not source.is_dir() or stored_motion_digest(source) != digest:
                raise BundleRefused(f"{records.MOTION}{digest}/: the submitted motion of {system.name} is missing or "
                                    "not the motion of its digest")
            for path in sorted(source.iterdir()):
                load_motion_npz(path, f"{records.MOTION}{digest}/{path.name}")
            target = Path(settings.CHECKPOINT_ROOT) / folder
            if not target.exists():
                shutil.copytree(source, self.placing.enter_context(atomic_folder(target)), dirs_exist_ok=True)

    # --- the clips -----------------------------------------------------------------

    def make_stimuli(self, study: Study) -> None:
        where = records.STIMULI_FILE
        data = _json(self.bundle, where)
        if not isinstance(data, list):
            raise records.RecordError(f"{where}: must be a list of stimuli")
        same_code = self.bundle.manifest.stimuli_code_version == CODE_VERSION
        for index, item in enumerate(data):
            here = f"{where}[{index}]"
            system, control, shown, video = (_pop(item, key, here) for key in
                                             ("system", "control", "shown_control", "video"))
            values = records.row_values(Stimulus, item, here)
            recorded_token = _file_name(values.get("token"), TOKEN, "token", here)
            stimulus = Stimulus(study=study, system=self._named(self.systems, system, here),
                                control=self._named(self.controls, control, here) if control is not None else None,
                                shown_control=self._named(self.controls, shown, here) if shown is not None else None,
                                **{**values, "token": _free(Stimulus, "token", recorded_token)})
            if stimulus.control is not None and same_code:
                try:
                    key = content_key(study, stimulus.system, stimulus.control, stimulus.seed, stimulus.shown_control)
                except StoredDataError as error:
                    raise records.RecordError(f"{here}: {error}") from None
                if key != stimulus.content_key:
                    raise records.RecordError(f"{here}: its content key is not that of its system, control and seed "
                                              "(the clip would not be the one rated)")
            uploaded = stimulus.system.source_kind == System.SourceKind.VIDEO
            if video is True or uploaded:
                stimulus.status, stimulus.duration_s = Stimulus.Status.DONE, self.video(recorded_token, stimulus)
            self.stimuli[recorded_token] = _saved(stimulus, here)
        by_key = {stimulus.content_key: stimulus for stimulus in self.stimuli.values()}
        for path in sorted(self.bundle.path(records.SAMPLED).glob("*")):
            name = f"{records.SAMPLED}{path.name}"
            if path.suffix != ".npz" or path.stem not in by_key:
                raise BundleRefused(f"{name}: sampled motion of no clip of the study")
            load_motion_npz(path, name)
            self.place_file(path, imported_sampled_path(by_key[path.stem]))  # this study's own, no other's cache

    def video(self, token: str, stimulus: Stimulus) -> float:
        """Check and place a clip's video; its duration."""
        name = f"{records.VIDEOS}{token}.mp4"
        path = self.bundle.path(name)
        if not path.is_file():
            raise BundleRefused(f"{name}: the video of a finished clip of {stimulus.system.name} is missing")
        try:
            duration = video_duration(path)
        except UploadRefused as error:
            raise BundleRefused(f"{name}: {error}") from None
        self.place_file(path, stimulus.video_path())
        return duration

    # --- who took part, and their answers ------------------------------------------------

    def make_participants(self, study: Study) -> None:
        where = records.PARTICIPANTS_FILE
        data = _json(self.bundle, where)
        for index, item in enumerate(_items(data, "participants", where)):
            here = f"{where}: participants[{index}]"
            training = _pop(item, "training", here)
            pages = _pop(item, "assignments", here)
            if not isinstance(training, list) or not isinstance(pages, list):
                raise records.RecordError(f"{here}: 'training' and 'assignments' must be lists")
            values = records.row_values(Participant, item, here)
            values["code"] = _free(Participant, "code", _id(values.get("code"), "code", here))
            practice = [self._named(self.stimuli, token, here).pk for token in training]
            participant = _saved(Participant(study=study, training=practice, **values), here,
                                 self._stamps(Participant, values))
            for position, page in enumerate(pages):
                there = f"{here}: assignments[{position}]"
                stimulus = self._named(self.stimuli, _pop(page, "stimulus", there), there)
                values = records.row_values(Assignment, page, there)
                recorded = _id(values.get("token"), "token", there)
                assignment = Assignment(participant=participant, stimulus=stimulus,
                                        **{**values, "token": _free(Assignment, "token", recorded)})
                self.assignments[recorded] = _saved(assignment, there)
        for index, item in enumerate(_items(data, "ratings", where)):
            here = f"{where}: ratings[{index}]"
            assignment = self._named(self.assignments, _pop(item, "assignment", here), here)
            values = _answer(study, records.row_values(Rating, item, here), here)
            _saved(Rating(assignment=assignment, **values), here, self._stamps(Rating, values))

    @staticmethod
    def _stamps(model, values: dict) -> dict:
        return {name: values[name] for name in records.auto_stamped(model) if name in values}

    @staticmethod
    def _named(rows: dict, name: object, where: str):
        if not isinstance(name, str) or name not in rows:
            raise records.RecordError(f"{where}: refers to {name!r}, which the bundle does not hold")
        return rows[name]


def _previous_run(bundle: ReadBundle, study: Study) -> None:
    """The bundle's ratings table and rules, kept as the rerun's previous run. The rules are
    read within bounds and checked as the analysis reads them now, so that a hostile or wrong
    rules.json is refused here, naming it, not on the study's report page later."""
    ratings, rules = _text(bundle, records.RATINGS_FILE), _text(bundle, records.RULES_FILE)
    _json(bundle, records.RULES_FILE)
    try:
        ExclusionRules.from_json(rules, records.RULES_FILE)
    except AnalysisInputError as error:
        raise records.RecordError(str(error)) from None
    _saved(PreviousRun(study=study, ratings_csv=ratings, rules_json=rules,
                       code_version=bundle.manifest.code_version), "the previous run")


# The keys of plan.json (``studyapp.preregistration.lock.preregistration``) and of each of its deviations.
PLAN_KEYS, DEVIATION_KEYS = {"locked", "plan", "sha256", "locked_at", "deviations"}, {"at", "field", "old", "new",
                                                                                     "recorded"}


def _restore_plan(bundle: ReadBundle, study: Study) -> None:
    """The original's locked plan and its recorded deviations, onto the imported study."""
    data, name = _json(bundle, records.PLAN_FILE), records.PLAN_FILE
    if not isinstance(data, dict) or not isinstance(data.get("locked"), bool):
        raise BundleRefused(f"{name}: expected an object with 'locked' true or false")
    if not data["locked"]:
        return
    if set(data) != PLAN_KEYS:
        raise BundleRefused(f"{name}: a locked plan has exactly the keys {', '.join(sorted(PLAN_KEYS))}")
    rows = data["deviations"]
    if not isinstance(rows, list) or not all(isinstance(row, dict) and set(row) == DEVIATION_KEYS for row in rows):
        raise BundleRefused(f"{name}: deviations must be objects of {', '.join(sorted(DEVIATION_KEYS))}")
    try:
        restore_preregistration(study, data)
    except (ValueError, TypeError, ValidationError) as error:
        raise BundleRefused(f"{name}: {error}") from None
    try:  # as the plan page, the monitor and the report will read it
        plan_markdown(preregistration(study))
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as error:
        raise BundleRefused(f"{name}: the plan lacks or garbles what a plan holds ({error!r})") from None


def _check_definition(bundle: ReadBundle, study: Study) -> None:
    """The bundle's definition must describe the study its records made (DefinitionError
    with its line where it is no definition; BundleRefused where it describes another)."""
    text = _bytes(bundle, records.DEFINITION_FILE)
    read_definition(text, records.DEFINITION_FILE)
    lines, made = text.decode(errors="replace").splitlines(), definition_yaml(study).splitlines()
    for number, (given, expected) in enumerate(zip(lines, made), start=1):
        if given != expected:
            raise BundleRefused(f"{records.DEFINITION_FILE}:{number}: describes another study than the bundle's "
                                f"records ({given.strip()[:80]!r} where they give {expected.strip()[:80]!r})")
    if len(lines) != len(made):
        raise BundleRefused(f"{records.DEFINITION_FILE}: describes another study than the bundle's records "
                            "(its length differs)")


def import_study(stream: BinaryIO | str, owner, rerun: bool = False) -> Study:
    """The bundle in ``stream`` (a file object or a path) as a new, closed study of ``owner``;
    BundleRefused naming what is wrong, with nothing left behind."""
    with tempfile.TemporaryDirectory(prefix="study-bundle-") as folder:
        scratch = Path(folder)
        bundle = read_bundle(stream, scratch)
        try:
            with transaction.atomic(), ExitStack() as placing:  # files move into place just before the commit
                run = _Import(bundle, placing)
                study = run.make_study(owner)
                _check_definition(bundle, study)
                run.make_stimuli(study)
                if rerun:
                    _previous_run(bundle, study)
                else:
                    run.make_participants(study)
                    _restore_plan(bundle, study)
        except (records.RecordError, ReadRefused, DefinitionError, UploadRefused, MotionFileError,
                StoredDataError) as error:
            raise BundleRefused(str(error).replace(f"{scratch}/", "")) from None
    return study


__all__ = ["import_study"]
