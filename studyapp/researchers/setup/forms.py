"""Forms of the researcher's pages: the study itself, its systems, controls and generation.

The forms only collect input; what it means (and every check of an upload's content)
lives in the service modules ``stimuli.systems``, ``stimuli.controls`` and
``stimuli.clips``, which the management commands call too.
"""

from __future__ import annotations

import dataclasses

from django import forms
from django.conf import settings

from generation.control import PRESETS
from generation.render.camera import Camera
from measures.units import UNITS, parse_scale
from studyapp.bounds import bound_of
from studyapp.designs import registry as designs
from studyapp.models import TEMPERATURE, ControlSignal, Question, Stimulus, Study, System, camera_setting_problem
from studyapp.preregistration.fixed import INSTRUMENT, started


CAMERA_PREFIX = "camera_"
# The camera's fields in words; a field not named here is labelled by its name.
CAMERA_LABELS = {
    "azimuth": "Camera direction (degrees about the vertical)",
    "elevation": "Camera height (degrees above the horizon)",
    "distance": "Camera distance (cm)",
    "fov": "Field of view (degrees, vertical)",
    "target_height": "Aimed at (cm above the floor)",
    "follow": "Camera follows the character",
    "follow_smoothing": "Following smoothed over (s)",
    "near": "Nothing drawn nearer than (cm)",
    "figure_share": "Character's share of the frame height",
    "target_share": "Aimed at (share of the character's size)",
}
# Settings of answers on the scale, which a design without one (pairwise) does not show.
SCALE_SETTINGS = ("scale_min", "scale_max", "label_min", "label_max", "bad_threshold", "natural_threshold")


def _camera_field(spec: dataclasses.Field) -> forms.Field:
    """A form field for one field of ``Camera`` (a number, or a yes/no)."""
    label = CAMERA_LABELS.get(spec.name, spec.name.replace("_", " ").capitalize())
    if spec.type in ("bool", bool):
        return forms.BooleanField(required=False, label=label)
    if spec.default is None:  # the renderer derives it from the character's size
        return forms.FloatField(required=False, label=label, help_text="empty: from the character's size")
    return forms.FloatField(label=label)


class StudyForm(forms.ModelForm):
    """Every setting of a study, in sections; ``Study.clean`` checks them together.

    What participants are shown and judged by (the question, the scale and its labels,
    the attention-check thresholds, the camera and video size) is fixed once anyone has
    started: changing it would mix answers to two instruments in one table, re-read old
    ratings on a new scale, or add a second set of clips drawn differently. The camera
    is one field per ``Camera`` field, so a new camera setting appears here by itself.
    """

    INSTRUMENT = INSTRUMENT  # plan.fixed's, which the admin and the commands hold to as well
    SECTIONS = (
        ("The study", ("title", "instructions", "consent_text")),
        ("Design", ("design", "pages_per_participant", "abx", "preference_strengths", "adaptive_pairing",
                    "reasons", "reasons_required")),
        ("Question and scale", ("question", "scale_min", "scale_max", "label_min", "label_max")),
        ("Clips and targets", ("clips_per_participant", "ratings_per_stimulus", "training_clips",
                               "reservation_minutes", "path_tolerance_cm")),
        ("Attention checks and early answers", ("bad_checks", "natural_checks", "bad_threshold", "natural_threshold",
                                                "instructed_checks", "stop_after_failed_checks",
                                                "require_full_play", "sliders_must_move", "discard_early")),
        ("Plan", ("expected_effect",)),
        ("Crowd platform", ("platform", "completion_code", "redirect_url", "screen_out_code", "stopped_code",
                            "is_open")),
        ("Device check", ("device_check", "min_screen_width", "min_screen_height")),
        ("Video and camera", ("video_width", "video_height")),  # and every camera field
    )

    redirect_url = forms.URLField(required=False, assume_scheme="https", label="Completion URL",
                                  help_text=Study._meta.get_field("redirect_url").help_text)

    OPTIONAL_SIZES = ("min_screen_width", "min_screen_height")  # left empty: any size
    KEPT_WHEN_EMPTY = ("path_tolerance_cm",)  # left empty (a form from before the setting): as it is

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        for name in (*self.OPTIONAL_SIZES, *self.KEPT_WHEN_EMPTY):
            self.fields[name].required = False
        model_fields = {field.name for field in Study._meta.concrete_fields}
        for name in model_fields & set(self.fields):  # the browser holds to the bounds of Study's validators too
            if bound := bound_of(Study, name):
                self.fields[name].widget.attrs.update(min=f"{bound.low:g}", max=f"{bound.high:g}")
        stored = self.instance.camera if isinstance(self.instance.camera, dict) else {}  # saving replaces a broken one
        camera = {**Camera().to_dict(), **stored}
        for spec in dataclasses.fields(Camera):
            field = self.fields[CAMERA_PREFIX + spec.name] = _camera_field(spec)
            field.initial = camera.get(spec.name)
        if self.instance.pk and started(self.instance):
            for name in [*self.INSTRUMENT, *self.camera_fields()]:
                self.fields[name].disabled = True  # posted values are ignored
                self.fields[name].help_text = "fixed: participants have started this study"

    def camera_fields(self) -> list[str]:
        return [name for name in self.fields if name.startswith(CAMERA_PREFIX)]

    def chosen_design(self) -> str:
        """The design the form shows its fields for: the posted one, else the study's."""
        posted = self.data.get("design") if self.is_bound else None
        return posted if posted in designs.DESIGNS else self.instance.design

    @staticmethod
    def field_designs(name: str) -> list[str]:
        """The designs a setting matters to: every design but those another design's
        setting belongs to (``Design.settings``) and, for a scale's setting, those whose
        answers are not on a scale."""
        return [each for each in designs.DESIGNS
                if name not in designs.foreign_settings(each)
                and not (name in SCALE_SETTINGS and not designs.design_named(each).on_scale)]

    def sections(self) -> list[tuple[str, list[tuple[forms.BoundField, str | None]]]]:
        """The fields in their sections, each with the designs it matters to (None: all),
        space-separated; any field no section names goes in the last, "Other settings"."""
        placed = {name for _, names in self.SECTIONS for name in names} | set(self.camera_fields())
        sections = [(title, [name for name in names if name in self.fields]) for title, names in self.SECTIONS]
        sections[-1][1].extend(self.camera_fields())
        others = [name for name in self.fields if name not in placed]
        sections += [("Other settings", others)] if others else []
        every = list(designs.DESIGNS)

        def shown(name: str) -> tuple[forms.BoundField, str | None]:
            owners = self.field_designs(name)
            return self[name], None if owners == every else " ".join(owners)

        return [(title, [shown(name) for name in names]) for title, names in sections]

    def clean(self) -> dict:
        for name in self.OPTIONAL_SIZES:
            if self.cleaned_data.get(name) is None and name not in self.errors:
                self.cleaned_data[name] = 0
        for name in self.KEPT_WHEN_EMPTY:
            if self.cleaned_data.get(name) is None and name not in self.errors:
                self.cleaned_data[name] = getattr(self.instance, name)
        camera = {name[len(CAMERA_PREFIX):]: self.cleaned_data.get(name) for name in self.camera_fields()}
        for setting, value in camera.items():
            if CAMERA_PREFIX + setting not in self.errors and (problem := camera_setting_problem(setting, value)):
                self.add_error(CAMERA_PREFIX + setting, problem)
        if not any(name in self.errors for name in self.camera_fields()):
            try:
                self.instance.camera = Camera.from_dict(camera).to_dict()
            except ValueError as error:
                raise forms.ValidationError(f"camera: {error}") from None
        cleaned = super().clean()
        changed = set(self.changed_data)
        # A design with a scale of its own (side-by-side's 0-100 sliders, as HEMVIP and
        # GENEA) gets it when chosen, unless the researcher sets one.
        default_scale = designs.design_named(cleaned["design"]).default_scale if cleaned.get("design") else None
        if default_scale and "design" in changed and not changed & {"scale_min", "scale_max"}:
            cleaned["scale_min"], cleaned["scale_max"] = default_scale
        return cleaned

    class Meta:
        model = Study
        exclude = ["owner", "camera", "previewed_at", "display_figure"]  # the figure comes from the systems' rigs
        labels = {
            "pages_per_participant": "Pages per participant",
            "abx": "Natural clip shown as a reference (ABX)",
            "preference_strengths": "Degrees of preference",
            "adaptive_pairing": "Adaptive pairing (pairs chosen from the votes so far)",
            "reasons": "Reasons asked with each answer (one a line)",
            "reasons_required": "A reason is required",
            "scale_min": "Lowest rating",
            "scale_max": "Highest rating",
            "label_min": "Lowest rating's label",
            "label_max": "Highest rating's label",
            "clips_per_participant": "Clips per participant",
            "ratings_per_stimulus": "Ratings per clip (target)",
            "training_clips": "Practice clips",
            "reservation_minutes": "Clips held for an idle participant (minutes)",
            "bad_checks": "BAD checks per participant",
            "natural_checks": "NAT checks per participant",
            "bad_threshold": "Exclude who rates a BAD clip at or above",
            "natural_threshold": "Exclude who rates a NAT clip below",
            "instructed_checks": "Instructed checks per participant",
            "stop_after_failed_checks": "Stop after failed instructed checks",
            "require_full_play": "Answers unlock when the clip has played",
            "sliders_must_move": "Each slider must be moved before answering",
            "discard_early": "Flag answers given before the clip ended",
            "completion_code": "Completion code",
            "is_open": "Open to participants",
            "expected_effect": "Expected effect (optional)",
            "device_check": "Check the device before consent",
            "min_screen_width": "Smallest screen width (px)",
            "min_screen_height": "Smallest screen height (px)",
            "video_width": "Video width (px)",
            "video_height": "Video height (px)",
        }
        widgets = {
            "instructions": forms.Textarea(attrs={"rows": 4}),
            "consent_text": forms.Textarea(attrs={"rows": 4}),
            "reasons": forms.Textarea(attrs={"rows": 4}),
        }


class QuestionForm(forms.ModelForm):
    """One question; ``Question.clean`` checks its choices and its answers' range, and the
    unique name is checked against the study's other questions (the instance carries the study)."""

    RANGE = ("minimum", "maximum")  # number questions only; left empty, the defaults (an age in years)

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        for name in self.RANGE:
            self.fields[name].required = False

    def clean(self) -> dict:
        for name in self.RANGE:
            if self.cleaned_data.get(name) is None and name not in self.errors:
                self.cleaned_data[name] = Question._meta.get_field(name).default
        return super().clean()

    class Meta:
        model = Question
        fields = ["part", "name", "text", "kind", "choices", "accepted", "required", "minimum", "maximum", "whole_numbers"]
        widgets = {"choices": forms.Textarea(attrs={"rows": 3}), "accepted": forms.Textarea(attrs={"rows": 2})}

    def validate_unique(self) -> None:
        others = Question.objects.filter(study=self.instance.study).exclude(pk=self.instance.pk)
        if others.filter(name=self.cleaned_data.get("name")).exists():
            self.add_error("name", "another question of this study has this name")


class QuestionRemovalForm(forms.Form):
    """The question to remove: one of the study's, by id (any other value is this form's error)."""

    question = forms.ModelChoiceField(queryset=Question.objects.none(),
                                      error_messages={"invalid_choice": "no question of this study has the id %(value)s",
                                                      "required": "say which question to remove"})

    def __init__(self, *args, study: Study, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.fields["question"].queryset = study.questions.all()


def _megabytes(limit: int) -> str:
    return f"at most {limit / 1e6:.0f} MB"


class CheckpointSystemForm(forms.Form):
    name = forms.CharField(max_length=60, help_text="shown to you only; participants never see it")
    role = forms.ChoiceField(choices=[(System.Role.MODEL, "model"), (System.Role.BAD, "BAD (an early or weakened checkpoint)")])
    temperature = forms.FloatField(initial=1.0, min_value=TEMPERATURE.low, max_value=TEMPERATURE.high,
                                   help_text="sampling temperature")
    checkpoint = forms.FileField(help_text=f"a .safetensors checkpoint of this project, "
                                           f"{_megabytes(settings.MAX_CHECKPOINT_UPLOAD_BYTES)}")


class SystemEditForm(forms.Form):
    """A system's name and, for one sampled from a checkpoint (``sampled``), its temperature."""

    name = forms.CharField(max_length=System._meta.get_field("name").max_length,
                           help_text="shown to you only; participants never see it")
    temperature = forms.FloatField(min_value=TEMPERATURE.low, max_value=TEMPERATURE.high,
                                   help_text="sampling temperature: a new one deletes the system's clips; generating "
                                             "the stimuli samples them again")

    def __init__(self, *args, sampled: bool = True, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        if not sampled:
            del self.fields["temperature"]


class ControlEditForm(forms.Form):
    name = forms.CharField(max_length=ControlSignal._meta.get_field("name").max_length,
                           help_text="its clips stay as they are")


class NaturalSystemForm(forms.Form):
    name = forms.CharField(max_length=60, initial="NAT")


class MultipleFileInput(forms.ClearableFileInput):
    allow_multiple_selected = True


class MultipleFileField(forms.FileField):
    """Several files in one field (Django's documented pattern)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("widget", MultipleFileInput(attrs={"accept": "video/mp4,.mp4"}))
        super().__init__(*args, **kwargs)

    def clean(self, data, initial=None):
        files = data if isinstance(data, (list, tuple)) else [data]
        return [super(MultipleFileField, self).clean(item, initial) for item in files]


class MotionUnitsForm(forms.Form):
    """The BVH files' length unit and up axis, detected unless given, as every command of
    ``python -m generation`` takes them (``--scale``, ``--up``). Cleaned, ``unit`` is the
    factor to centimetres and ``up`` the axis, None where detected."""

    unit = forms.CharField(required=False, initial="auto", max_length=30, label="Length unit",
                           help_text=f"auto or empty (from the skeleton's size), {', '.join(UNITS)} "
                                     "(CMU's 5.64 cm), or centimetres per unit")
    up = forms.ChoiceField(required=False, choices=[("auto", "auto (from the floor)"), ("y", "y"), ("z", "z")],
                           initial="auto", label="Up axis")

    def clean_unit(self) -> float | None:
        try:
            return parse_scale(self.cleaned_data["unit"] or "auto")
        except ValueError as error:
            raise forms.ValidationError(str(error)) from None

    def clean_up(self) -> str | None:
        return self.cleaned_data["up"] if self.cleaned_data["up"] in ("y", "z") else None


class SubmittedMotionSystemForm(MotionUnitsForm):
    name = forms.CharField(max_length=60, help_text="shown to you only; participants never see it")
    role = forms.ChoiceField(choices=[(System.Role.MODEL, "model"), (System.Role.BAD, "BAD")])
    motion = forms.FileField(help_text="a .zip of the lab's BVH files as they are (any unit, y or z up, starting "
                                       "anywhere) or .npz, one per control named by its id (or ID_NN.bvh), "
                                       f"{_megabytes(settings.MAX_MOTION_UPLOAD_BYTES)}")
    keep_root = forms.BooleanField(required=False, label="Keep the root where it is",
                                   help_text="leave each clip where it was captured instead of moving its start to "
                                             "the control's (the origin, facing +z)")

    field_order = ["name", "role", "motion", "unit", "up", "keep_root"]


class VideoSystemForm(forms.Form):
    name = forms.CharField(max_length=60, initial="BAD")
    role = forms.TypedChoiceField(required=False, empty_value=System.Role.BAD,
                                  choices=[(System.Role.BAD, "BAD (attention checks)"),
                                           (System.Role.MODEL, "model (rendered elsewhere: not the study's camera)")])
    videos = MultipleFileField(help_text=f"MP4 files, each {_megabytes(settings.MAX_VIDEO_UPLOAD_BYTES)}")


class HeldOutControlsForm(MotionUnitsForm):
    seconds = forms.FloatField(initial=4.0, min_value=0.5, max_value=60.0, help_text="each clip is cut to this")
    count = forms.IntegerField(required=False, min_value=1, max_value=1000, initial=6,
                               help_text="how many held-out clips, spread over their content labels (empty: all)")
    lead_in = forms.FloatField(required=False, initial=1.0, min_value=0.0, max_value=60.0, label="Lead-in",
                               help_text="seconds of each take before its clip, which path-controlled models warm up "
                                         "on and NAT leaves out; 0 or empty starts at the take's first frame")
    takes = forms.CharField(required=False, max_length=2000, label="Takes",
                            help_text="these takes (file names without .bvh, separated by commas or spaces) instead "
                                      "of those the seeded split holds out")

    field_order = ["seconds", "count", "lead_in", "takes", "unit", "up"]

    def __init__(self, *args, paths: bool = True, trained: bool = True, **kwargs):
        super().__init__(*args, **kwargs)
        if not paths:  # a label-controlled model has no path to warm up on
            del self.fields["lead_in"]
        if trained:  # the checkpoints read their data in the unit and up axis they were trained in
            del self.fields["unit"], self.fields["up"]

    def clean_takes(self) -> list[str]:
        return self.cleaned_data["takes"].replace(",", " ").split()


class PresetControlsForm(forms.Form):
    presets = forms.MultipleChoiceField(choices=[(name, name) for name in PRESETS], widget=forms.CheckboxSelectMultiple)


class LabelControlsForm(forms.Form):
    """Every chosen action with every chosen style, for label-controlled models."""

    actions = forms.MultipleChoiceField(widget=forms.CheckboxSelectMultiple)
    styles = forms.MultipleChoiceField(widget=forms.CheckboxSelectMultiple)
    seconds = forms.FloatField(initial=4.0, min_value=0.5, max_value=60.0)

    def __init__(self, *args, labels: tuple[list[str], list[str]] = ([], []), **kwargs) -> None:
        super().__init__(*args, **kwargs)
        for field, names in zip(("actions", "styles"), labels):
            self.fields[field].choices = [(name, name) for name in names]


class ControlFileForm(forms.Form):
    description = forms.FileField(help_text="a JSON or YAML path description (one path or a list), "
                                            "its numbers as JSON writes them (docs/running-a-study.md)")


class GenerateForm(forms.Form):
    seed = forms.IntegerField(initial=0, min_value=0, max_value=Stimulus.MAX_SEED,
                              help_text="random seed of every model's samples")


class BundleImportForm(forms.Form):
    bundle = forms.FileField(help_text=f"a study bundle (.zip) that export_study or a study page wrote, "
                                       f"{_megabytes(settings.MAX_BUNDLE_UPLOAD_BYTES)}")
    rerun = forms.BooleanField(required=False, label="Rerun",
                               help_text="import the design, systems, controls and clips but not the participants: "
                                         "a new run for new participants, whose report compares its ratings with "
                                         "the bundle's")

    def clean_bundle(self):
        bundle = self.cleaned_data["bundle"]
        if not bundle.name.lower().endswith(".zip"):
            raise forms.ValidationError(f"{bundle.name}: a study bundle is a .zip file")
        if bundle.size > settings.MAX_BUNDLE_UPLOAD_BYTES:
            raise forms.ValidationError(f"{bundle.name}: {bundle.size / 1e6:.1f} MB is over the "
                                        f"{_megabytes(settings.MAX_BUNDLE_UPLOAD_BYTES)} limit")
        return bundle
