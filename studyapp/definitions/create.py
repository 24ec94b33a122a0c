"""Making a study from its definition, through the same checks as the study's pages.

The study's settings go through the study page's form (``StudyForm``: every bound and
``Study.clean``), each question through the questions page's form, each system and
control through the services the systems and controls pages call (``stimuli.systems``,
``stimuli.submissions``, ``stimuli.controls``). This module only reads the definition
into their inputs (a value of the wrong type or under an unknown key is refused here,
before any of them sees it) and says on which line of the file each of their refusals
is. A checkpoint or submitted motion is named by its digest and must be the owner's
(one their systems were made of, which the systems page keeps in the checkpoint store,
``CHECKPOINT_ROOT``) or a shared checkpoint; a held-out control's folders must be ones
the owner may name (``studyapp.ownership``, asked before anything reads them).

Everything is made in one transaction: a definition refused anywhere leaves no row.
"""

from __future__ import annotations

import secrets
from pathlib import Path as FilePath

import numpy as np
from django import forms
from django.contrib.auth.base_user import AbstractBaseUser
from django.core.exceptions import ValidationError
from django.core.files import File
from django.db import transaction

from generation import registry
from generation.control import PathControl
from generation.render.camera import Camera
from generation.checkpoints.store import SHA256_HEX
from studyapp import ownership
from studyapp.bounds import check_field
from studyapp.definitions import layout
from studyapp.definitions.errors import DefinitionError
from studyapp.definitions.reading import Located, Path, read_definition
from studyapp.designs import registry as designs
from studyapp.models import SAFE_ID, ControlSignal, Question, Study, System
from studyapp.researchers.setup.editing import EditRefused, rename_control
from studyapp.researchers.setup.forms import (CAMERA_PREFIX, HeldOutControlsForm, LabelControlsForm, QuestionForm,
                                       StudyForm)
from studyapp.stimuli.controls import (ControlError, add_held_out_controls, add_label_controls, add_path_control,
                                       add_preset_controls, control_kind, shorter_than_asked_warnings, study_labels)
from studyapp.stimuli.submissions import Reading, add_submitted_system, read_folder
from studyapp.stimuli.systems import UploadRefused, add_checkpoint_system, add_natural_system


def _where(path: Path) -> str:
    return "".join(f"[{part}]" if isinstance(part, int) else f".{part}" for part in path).lstrip(".") or "the file"


def _is(value: object, expected: type | tuple[type, ...]) -> bool:
    kinds = expected if isinstance(expected, tuple) else (expected,)
    return any(type(value) is kind or (kind is float and type(value) is int) for kind in kinds)


class _Builder:
    """One definition being made into a study: its values, their lines, the problems found."""

    def __init__(self, located: Located, owner: AbstractBaseUser, source: str) -> None:
        self.located, self.owner, self.source = located, owner, source
        self.problems: list[tuple[int | None, str]] = []

    # Reading the values, recording every problem with its line.

    def problem(self, path: Path, message: str) -> None:
        self.problems.append((self.located.line(path), message))

    def fail(self, path: Path, message: str) -> DefinitionError:
        return DefinitionError(self.source, [*self.problems, (self.located.line(path), message)])

    def stop(self) -> None:
        """Raise the problems found so far, if any."""
        if self.problems:
            raise DefinitionError(self.source, self.problems)

    def mapping(self, path: Path, value: object, types: dict, required: tuple[str, ...] = ()) -> dict:
        """The entries of ``value`` that are known and of their type (a problem for every other)."""
        if not isinstance(value, dict):
            self.problem(path, f"{_where(path)} must be a mapping of settings, not {layout.value_words(value)}")
            return {}
        for key in value:
            if key not in types:
                self.problem((*path, key), f"unknown setting {key!r} in {_where(path)} (known: {', '.join(types)})")
        for key in required:
            if key not in value:
                self.problem(path, f"{_where(path)} needs {key!r}")
        checked = {}
        for key, item in value.items():
            if key in types and not _is(item, types[key]):
                self.problem((*path, key), f"{_where((*path, key))} must be {layout.type_words(types[key])}, "
                                           f"not {layout.value_words(item)}")
            elif key in types:
                checked[key] = item
        return checked

    def items(self, key: str) -> list:
        value = self.located.value.get(key)
        value = [] if value is None else value  # "questions:" with none under it
        if not isinstance(value, list):
            self.problem((key,), f"{key} must be a list, not {layout.value_words(value)}")
            return []
        return value

    def texts(self, path: Path, value: list) -> list[str]:
        for i, item in enumerate(value):
            if not isinstance(item, str):
                self.problem((*path, i), f"{_where((*path, i))} must be text, not {layout.value_words(item)}")
        return [item for item in value if isinstance(item, str)]

    def form_problems(self, form: forms.Form, path: Path, keys: dict[str, str]) -> None:
        """Raise a page form's refusals of the values under ``path`` (``keys``: a form field's key there)."""
        if not form.is_valid():
            for name, messages in form.errors.items():
                where = (*path, keys.get(name, name)) if name != "__all__" else path
                self.problem(where, f"{_where(where)}: {' '.join(messages)}")
            self.stop()

    def owned(self, path: Path, kind: str, name: str) -> FilePath:
        """Where the ``kind`` that ``name`` names lies, if it is the owner's or shared (``studyapp.ownership``)."""
        try:
            return ownership.owned(self.owner, kind, name)
        except ownership.NotYours as error:
            raise self.fail(path, f"{_where(path)}: {error}") from None

    def digest(self, path: Path, value: str) -> str:
        if not SHA256_HEX.fullmatch(value):
            raise self.fail(path, f"{_where(path)} must be a SHA-256 digest (64 hexadecimal digits), not {value[:80]!r}")
        return value

    # The study and its questions, through the forms of their pages.

    def study(self) -> Study:
        top = self.located.value
        sections = layout.study_sections()
        known = [layout.VERSION_KEY, *(key for key, _ in sections), *layout.LISTS]
        for key in top:
            if key not in known:
                self.problem((key,), f"unknown section {key!r} (known: {', '.join(known)})")
        if top.get(layout.VERSION_KEY) != layout.VERSION:
            self.problem((layout.VERSION_KEY,) if layout.VERSION_KEY in top else (),
                         f"{layout.VERSION_KEY} must be {layout.VERSION}, the version of study definitions this "
                         f"server reads, not {top.get(layout.VERSION_KEY)!r}")
        types, camera_section = layout.study_types(), layout.camera_section()
        camera_path = (camera_section, layout.CAMERA_KEY)
        home = {name: (key, name) for key, names in sections for name in names}
        given = {}
        for key, names in sections:
            section_types = {name: types[name] for name in names} | ({layout.CAMERA_KEY: dict} if key == camera_section
                                                                     else {})
            section = top.get(key)
            given |= self.mapping((key,), {} if section is None else section, section_types)
        camera = self.mapping(camera_path, given.pop(layout.CAMERA_KEY, {}), layout.camera_types())
        self.stop()
        data = {name: Study._meta.get_field(name).get_default() for name in home} | given
        scale = designs.DESIGNS.get(data["design"]) and designs.design_named(data["design"]).default_scale
        if scale and not {"scale_min", "scale_max"} & set(given):  # the design's own, as the study page gives it
            data["scale_min"], data["scale_max"] = scale
        data |= {CAMERA_PREFIX + name: value for name, value in {**Camera().to_dict(), **camera}.items()}
        form = StudyForm(data, instance=Study(owner=self.owner, design=data["design"]))
        if not form.is_valid():
            for name, messages in form.errors.items():
                if name in home:
                    path, where = home[name], _where(home[name])
                elif name.startswith(CAMERA_PREFIX):
                    path = (*camera_path, name.removeprefix(CAMERA_PREFIX))
                    where = _where(path)
                else:  # Study.clean's word on the whole study (its camera, as the study page shows it)
                    path, where = camera_path, "the study"
                for message in messages:
                    self.problem(path, f"{where}: {message}")
            self.stop()
        study = form.save(commit=False)
        study.owner = self.owner
        study.save()
        return study

    def questions(self, study: Study) -> None:
        types, places = layout.question_types(), {}
        for i, entry in enumerate(self.items("questions")):
            path = ("questions", i)
            given = self.mapping(path, entry, types, layout.QUESTION_REQUIRED)
            for name in layout.QUESTION_LISTS:  # one choice a line, as the questions page takes them
                items = self.texts((*path, name), given.get(name, []))
                for j, item in enumerate(items):
                    if "\n" in item or "\r" in item:
                        self.problem((*path, name, j), f"{_where((*path, name, j))}: a choice is one line")
                given[name] = "\n".join(items)
            if self.problems:
                continue
            data = {name: Question._meta.get_field(name).get_default() for name in types} | given
            order = places[data["part"]] = places.get(data["part"], -1) + 1  # as listed, within its part
            form = QuestionForm(data, instance=Question(study=study, order=order))
            if form.is_valid():
                form.save()
            for name, messages in form.errors.items():
                for message in messages:
                    where = (*path, name) if name in types else path
                    self.problem(where, f"{_where(where)}: {message}")
        self.stop()

    # Systems and controls, through the services of the systems and controls pages.

    def systems(self) -> list[tuple[Path, dict, str | None]]:
        """Each system's path, settings and source (None: the natural clips), checked."""
        types, required = layout.types(layout.SYSTEM_KEYS), layout.required(layout.SYSTEM_KEYS)
        found = []
        for i, entry in enumerate(self.items("systems")):
            path = ("systems", i)
            given = self.mapping(path, entry, types, required)
            sources = [key for key in layout.SYSTEM_SOURCES if key in given]
            if "name" in given and (problem := check_field(System, "name", given["name"])):
                self.problem((*path, "name"), f"{_where(path)}: {problem}")
            if "figure" in given and (problem := check_field(System, "figure_mapping", given["figure"])):
                self.problem((*path, "figure"), f"{_where(path)}: {problem}")
            if len(sources) > 1:
                self.problem(path, f"{_where(path)}: give one of {', '.join(layout.SYSTEM_SOURCES)}, not "
                                   f"{' and '.join(sources)}")
            if "temperature" in given and sources != ["checkpoint"]:
                self.problem((*path, "temperature"), f"{_where(path)}: only a checkpoint is sampled at a temperature")
            found.append((path, given, sources[0] if sources else None))
        self.stop()
        return found

    def checkpoint_system(self, study: Study, path: Path, given: dict) -> None:
        where = (*path, "checkpoint")
        spec = self.mapping(where, given["checkpoint"], layout.types(layout.CHECKPOINT_KEYS),
                            layout.required(layout.CHECKPOINT_KEYS))
        self.stop()
        digest = self.digest((*where, "digest"), spec["digest"])
        stored = self.owned((*where, "digest"), ownership.CHECKPOINT, digest)
        try:
            with File(stored.open("rb"), name=spec["file"]) as upload:
                system = add_checkpoint_system(study, given["name"], upload, given["role"], given.get("temperature", 1.0))
        except UploadRefused as error:
            raise self.fail(path, f"{_where(path)}: {error}") from None
        if system.checkpoint_digest != digest:
            raise self.fail((*where, "digest"), f"the stored checkpoint {digest} reads as another "
                                                f"({system.checkpoint_digest})")
        if spec.get("kind", system.kind) != system.kind:
            raise self.fail((*where, "kind"), f"the checkpoint {digest[:12]} is a {system.kind} model, not {spec['kind']}")

    def submitted_spec(self, path: Path, given: dict) -> dict:
        spec = self.mapping((*path, "submitted"), given["submitted"], layout.types(layout.SUBMITTED_KEYS),
                            layout.required(layout.SUBMITTED_KEYS))
        spec["controls"] = self.texts((*path, "submitted", "controls"), spec.get("controls", []))
        return spec

    def submitted_system(self, study: Study, path: Path, given: dict, spec: dict) -> None:
        where = (*path, "submitted")
        digest = self.digest((*where, "digest"), spec["digest"])
        folder = self.owned((*where, "digest"), ownership.SUBMITTED_MOTION, digest)
        try:  # the stored clips are already the body, on the control's path: read again, as they are
            system = add_submitted_system(study, given["name"], read_folder(folder), given["role"], spec.get("file", ""),
                                          Reading(keep_root=True), given.get("figure"))
        except (UploadRefused, ControlError) as error:  # a submission's report: one control a line
            said = "; ".join(getattr(error, "lines", None) or [str(error)])
            raise self.fail(path, f"{_where(path)}: the submitted motion was not registered: {said}") from None
        if system.checkpoint_digest != digest:
            raise self.fail((*where, "digest"), f"the stored motion {digest[:12]} reads as other motion "
                                                f"({system.checkpoint_digest[:12]})")

    def control_entries(self) -> list[tuple[Path, dict, str]]:
        """Each control's path, settings and what it is made from, checked."""
        types, required = layout.types(layout.CONTROL_KEYS), layout.required(layout.CONTROL_KEYS)
        found = []
        for i, entry in enumerate(self.items("controls")):
            path = ("controls", i)
            given = self.mapping(path, entry, types, required)
            sources = [key for key in layout.CONTROL_SOURCES if key in given]
            if "name" in given and (problem := check_field(ControlSignal, "name", given["name"])):
                self.problem((*path, "name"), f"{_where(path)}: {problem}")
            if len(sources) != 1:
                self.problem(path, f"{_where(path)}: give one of {', '.join(layout.CONTROL_SOURCES)}"
                                   + (f", not {' and '.join(sources)}" if sources else ""))
            else:
                found.append((path, given, sources[0]))
        self.stop()
        return found

    def controls(self, study: Study, entries: list[tuple[Path, dict, str]]) -> None:
        """Controls made by their services under passing names, then renamed to their own
        and given their export ids (so no control's first name collides with another's own)."""
        made: list[tuple[Path, dict, ControlSignal]] = []
        for path, given, source in entries:
            try:
                control = self.control(study, path, source, given[source], given["name"])
            except ControlError as error:
                raise self.fail((*path, source), f"{_where(path)}: {error}") from None
            control.name = f"~{secrets.token_hex(8)}"
            control.save(update_fields=["name"])
            made.append((path, given, control))
        exported = set(study.controls.exclude(export_id="").exclude(pk__in=[c.pk for _, _, c in made])
                       .values_list("export_id", flat=True))  # those of the controls made before
        for path, given, control in made:
            try:
                rename_control(control, given["name"])  # as the controls page renames: its description too
                control.export_id = given.get("export_id", control.export_id)
                control.full_clean()
            except EditRefused as error:
                self.problem((*path, "name"), f"{_where(path)}: {error}")
                continue
            except ValidationError as error:
                for name, messages in error.message_dict.items():
                    self.problem((*path, name), f"{_where(path)}: {name}: {' '.join(messages)}")
                continue
            if control.export_id and not SAFE_ID.fullmatch(control.export_id):
                self.problem((*path, "export_id"), f"{_where(path)}: an export id is a plain file name (letters, "
                                                   f"digits, _ . + -), not {control.export_id[:100]!r}")
            elif control.export_id in exported:
                self.problem((*path, "export_id"), f"{_where(path)}: the export id {control.export_id!r} is "
                                                   f"another control's too")
            elif control.export_id:
                exported.add(control.export_id)
            control.save(update_fields=["export_id"])
        self.stop()

    def control(self, study: Study, path: Path, source: str, value: object, given_name: str) -> ControlSignal:
        where = (*path, source)
        if source == "preset":
            return add_preset_controls(study, [value])[0]
        if source == "labels":  # checked as the controls page checks its label pairs
            spec = self.mapping(where, value, layout.types(layout.LABEL_KEYS), layout.required(layout.LABEL_KEYS))
            self.stop()
            form = LabelControlsForm({"actions": [spec["action"]], "styles": [spec["style"]],
                                      "seconds": spec["seconds"]}, labels=study_labels(study))
            self.form_problems(form, where, {"actions": "action", "styles": "style"})
            return add_label_controls(study, [spec["action"]], [spec["style"]], form.cleaned_data["seconds"])[0]
        if source == "path":
            spec = self.mapping(where, value, layout.types(layout.PATH_KEYS), layout.required(layout.PATH_KEYS))
            self.stop()
            try:
                velocities = np.asarray(spec["velocities"], dtype=np.float64)
                signal = PathControl(velocities, float(spec["fps"]), given_name)
            except (ValueError, TypeError) as error:
                raise self.fail((*where, "velocities"), f"{_where(where)}: not a path ({error})") from None
            return add_path_control(study, signal)
        spec = self.mapping(where, value, layout.types(layout.HELD_OUT_KEYS), layout.required(layout.HELD_OUT_KEYS))
        folders = self.texts((*where, "folders"), spec.get("folders", []))
        self.stop()
        for i, folder in enumerate(folders):  # before anything reads them: a folder not theirs is not looked into
            self.owned((*where, "folders", i), ownership.MOTION_FOLDER, folder)
        take = spec["take"]
        # Checked as the controls page checks its held-out form; the unit and up axis only
        # where the study has no checkpoint to fix them (the service refuses them otherwise).
        trained = study.systems.exclude(checkpoint="").exists()
        form = HeldOutControlsForm({"seconds": spec["seconds"], "lead_in": spec.get("lead_in", 0.0),
                                    "takes": FilePath(take).stem, "unit": "auto" if spec.get("unit") is None else str(spec["unit"]),
                                    "up": spec.get("up") or "auto"},
                                   paths=control_kind(study) == registry.PATH, trained=trained)
        self.form_problems(form, where, {"takes": "take"})
        chosen = form.cleaned_data
        controls = add_held_out_controls(study, chosen["seconds"], None, chosen.get("lead_in") or 0.0, folders or None,
                                         chosen["takes"], chosen.get("unit", spec.get("unit")),
                                         chosen.get("up", spec.get("up")))
        control = next((c for c in controls if c.source_clip == take), None)
        if control is None:
            raise self.fail((*where, "take"), f"{_where(where)}: {take} is not among the held-out takes of "
                                              f"{', '.join(folders) or 'MOTION_DATA'}")
        if shorter_than_asked_warnings([control], chosen["seconds"]):  # a definition asks for exactly what it names
            raise self.fail((*where, "seconds"), f"{_where((*where, 'seconds'))}: {take} lasts {control.seconds:.2f} s "
                                                 f"after its lead-in, not the {chosen['seconds']:g} s asked; ask for "
                                                 f"{control.seconds:.2f} s or less")
        return control

    def build(self) -> Study:
        study = self.study()
        self.questions(study)
        systems = self.systems()
        for path, given, source in systems:  # checkpoints first: the controls follow their data
            if source == "checkpoint":
                self.checkpoint_system(study, path, given)
        for path, given, source in systems:
            if source == "videos":
                raise self.fail((*path, "videos"), f"{_where(path)}: a system of uploaded videos cannot be made from a "
                                                   "definition, which does not hold its videos; add it on the systems page")
            if source is None and given["role"] != System.Role.NATURAL:
                raise self.fail((*path, "role"), f"{_where(path)}: a {given['role']} system needs a checkpoint, "
                                                 "submitted motion or videos; only NAT (role natural) has none")
            if source is None:
                try:
                    add_natural_system(study, given["name"])
                except UploadRefused as error:
                    raise self.fail(path, f"{_where(path)}: {error}") from None
            if source in (None, "checkpoint"):  # the display figure's mapping, as corrected (submitted: when added)
                study.systems.filter(name=given["name"]).update(figure_mapping=given.get("figure", {}))
        # Submitted motion is matched to the controls there are when it is added: each after
        # the controls it has clips of (fewest first), the other controls after them all.
        entries = self.control_entries()
        submitted = sorted(((path, given, self.submitted_spec(path, given)) for path, given, source in systems
                            if source == "submitted"), key=lambda item: len(item[2]["controls"]))
        self.stop()
        for path, given, spec in submitted:
            self.controls(study, [entry for entry in entries if entry[1]["name"] in spec["controls"]])
            entries = [entry for entry in entries if entry[1]["name"] not in spec["controls"]]
            self.submitted_system(study, path, given, spec)
        self.controls(study, entries)
        try:  # the settings again, now that the systems and controls they may depend on are there
            study.full_clean()
        except ValidationError as error:
            raise self.fail((), f"the study: {'; '.join(error.messages)}") from None
        return study


def create_study_from_definition(text: str | bytes, owner: AbstractBaseUser, *, source: str) -> Study:
    """A new, closed study owned by ``owner``, made from a definition's YAML ``text``
    (``describe.definition_yaml`` writes one); DefinitionError naming ``source`` and the
    line of each problem if it cannot be made, and then nothing is kept."""
    located = read_definition(text, source)
    with transaction.atomic():
        return _Builder(located, owner, source).build()
