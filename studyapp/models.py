"""The study's data: studies, their systems, control signals and stimuli, and the
participants' assignments and ratings.

Nothing a participant can see names a system: stimuli are served under a random token,
and the rating form names an assignment by another random token. Exclusions are flags
(``Participant.excluded``, ``Rating.answered_before_end``), never deletions.
"""

from __future__ import annotations

import math
import re
import secrets
from pathlib import Path

from django.conf import settings
from django.core.exceptions import ValidationError
from django.db import models

from analysis.levels import ALPHA, POWER
from analysis.designs import design_named as analysed_design
from generation.control import Control, control_from_dict
from generation.motion.data.dataset_options import DatasetOptions
from generation.render.camera import Camera
from generation.submission import PATH_TOLERANCE_CM
from generation.render.display_figure import PARENT, DisplayFigure, MappingError
from studyapp.bounds import Within, storable_json
from studyapp.designs import registry as designs
from studyapp.server.bucket_addresses import presigned_clip_url
from studyapp.server.clip_urls import signed_clip_url
from studyapp.server.media_bucket import in_bucket

NATURAL_NAME, ATTENTION_NAME = "NAT", "BAD"  # the names the analysis expects for these roles
# A name that is a plain file name on every system: a control's export id where its name is one.
SAFE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,99}")


class StoredDataError(ValueError):
    """A row holds data the study's code cannot read (an admin edit, an older version, a
    hand-made row); the message names the row and the field, for the researcher to fix or
    remove it in the admin (``admin_url``)."""

    def __init__(self, row: models.Model, field: str, problem: str) -> None:
        self.row, self.field = row, field
        super().__init__(f"{row._meta.verbose_name} {getattr(row, 'name', None) or str(row)!r} (id {row.pk}): "
                         f"its {field} {problem}")

    @property
    def admin_url(self) -> str:
        meta = self.row._meta
        return f"/admin/{meta.app_label}/{meta.model_name}/{self.row.pk}/change/"


def json_object(row: models.Model, field: str) -> dict:
    """A JSON field of ``row`` that must hold an object (StoredDataError if it does not)."""
    value = getattr(row, field)
    if not isinstance(value, dict):
        raise StoredDataError(row, field, f"is {type(value).__name__}, not a JSON object")
    return value


def figure_mapping_problem(value: object) -> None:
    """A system's mapping corrections must be a table of body points to joint names."""
    if not isinstance(value, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in value.items()):
        raise ValidationError("a mapping is a table of body points to joint names")
    if unknown := sorted(set(value) - set(PARENT)):
        raise ValidationError(f"no body point is called {', '.join(unknown)} (points: {', '.join(PARENT)})")


def display_figure_problem(value: object) -> None:
    """A study's display figure is empty (not planned yet) or a figure's description."""
    if value != {}:
        try:
            DisplayFigure.from_dict(value)
        except (MappingError, TypeError) as error:
            raise ValidationError(f"not a display figure: {error}") from None


def new_token() -> str:
    return secrets.token_hex(16)


def new_study_key() -> str:
    """A random key for the study's URLs and commands; never one that begins with "-",
    which a command line would read as an option (one key in 64 would)."""
    while (key := secrets.token_urlsafe(9)).startswith("-"):
        pass
    return key


def default_camera() -> dict:
    return Camera().to_dict()


# Camera fields whose None means "from the character's size" (generation.render.camera).
OPTIONAL_CAMERA_FIELDS = ("distance", "target_height")
# What the renderer can draw of a person (lengths in cm): farther than 100 m a figure is a
# few pixels tall, and a view narrower than a degree shows a few of its pixels.
CAMERA_BOUNDS = {
    "azimuth": Within(-360, 360, "degrees"),
    "distance": Within(20, 10_000, "cm: 100 m at most"),
    "fov": Within(1, 170, "degrees"),
    "target_height": Within(-10_000, 10_000, "cm"),
    "follow_smoothing": Within(0, 10, "seconds"),
    "near": Within(0.1, 1000, "cm"),
    "figure_share": Within(0.01, 2, "of the frame's height"),
    "target_share": Within(0, 2, "of the character's size"),
}


def camera_setting_problem(name: str, value: object) -> str | None:
    """What is wrong with one setting of a camera description, or None.

    JSON admits NaN and Infinity, which no database's JSON column stores and no
    renderer can draw, so every number must be finite, and within ``CAMERA_BOUNDS``.
    """
    if value is None and name in OPTIONAL_CAMERA_FIELDS:
        return None
    if name == "follow":
        return None if isinstance(value, bool) else f"'follow' must be true or false, got {value!r}"
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"{name!r} must be a number, got {value!r}"
    if not math.isfinite(value):
        return f"{name!r} must be a finite number, got {value}"
    bound = CAMERA_BOUNDS.get(name)
    return f"{name!r} {bound.message(value)}" if bound and not bound.low <= value <= bound.high else None


def camera_problem(data: object) -> str | None:
    """What makes ``data`` no camera description (a JSON object of Camera's fields), or None."""
    if not isinstance(data, dict):
        return f"expected a JSON object of camera fields, got {type(data).__name__}"
    for name, value in data.items():
        if problem := camera_setting_problem(name, value):
            return problem
    try:
        Camera.from_dict(data)
    except (TypeError, ValueError) as error:
        return str(error)
    return None


# The bounds of a study's numbers (``studyapp.bounds``), where they are shared or checked together.
SCALE_END = Within(-1000, 1000, "the ratings table's range")
CHECKS = Within(0, 50)
THRESHOLD = Within(0, 6, "on the 1-5 scale; 0 or 6, beyond its ends, turns the check off")
SCREEN_SIDE = Within(0, 7680, "CSS pixels of an 8K screen")
# The renderer draws every frame in memory and H.264 encoders stop at 4K frames.
VIDEO_SIDE = Within(64, 3840, "pixels: smaller shows no figure, larger is past 4K video")
MAX_VIDEO_PIXELS = 3840 * 2160


MAX_REASONS, MAX_REASON_CHARS = 12, 80  # a list a participant reads at a glance


def reason_lines(text: str) -> list[str]:
    """A study's reasons: its ``reasons`` text's non-empty lines, stripped."""
    return [line.strip() for line in (text or "").splitlines() if line.strip()]


def reasons_problem(text: str) -> None:
    """ValidationError for a reasons list a page cannot show as checkboxes."""
    lines = reason_lines(text)
    if len(lines) > MAX_REASONS:
        raise ValidationError(f"at most {MAX_REASONS} reasons (one a line), not {len(lines)}")
    if long := [line for line in lines if len(line) > MAX_REASON_CHARS]:
        raise ValidationError(f"a reason is at most {MAX_REASON_CHARS} characters: {long[0][:40]!r}... is "
                              f"{len(long[0])}")
    if len({line.casefold() for line in lines}) < len(lines):
        raise ValidationError("each reason once: the list names one twice")
    if any(line.casefold() == "other" for line in lines):
        raise ValidationError("\"Other\" is offered with its text field beside the reasons; leave it out of the list")
    if any(c in line for line in lines for c in "<>"):
        raise ValidationError("a reason is plain text: no < or >")


class Study(models.Model):
    """One rating study: its question, scale, design, protocol and crowd platform."""

    class Platform(models.TextChoices):
        PROLIFIC = "prolific", "Prolific"
        MTURK = "mturk", "Amazon Mechanical Turk"
        LINK = "link", "A plain link"

    class Language(models.TextChoices):
        """The languages participant pages come in (each with its studyapp/locale catalogue)."""

        ENGLISH = "en", "English"
        GERMAN = "de", "German (Deutsch)"

    owner = models.ForeignKey(settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="studies")
    title = models.CharField(max_length=200)
    # The participants' entry link carries this key; it says nothing about the study.
    key = models.CharField(max_length=32, unique=True, default=new_study_key, editable=False)
    question = models.CharField(max_length=300, default="How natural does the motion of the character look?")
    scale_min = models.SmallIntegerField(default=1, validators=[SCALE_END])
    scale_max = models.SmallIntegerField(default=5, validators=[SCALE_END])
    label_min = models.CharField(max_length=60, default="Completely unnatural")
    label_max = models.CharField(max_length=60, default="Completely natural")
    instructions = models.TextField(default=(
        "You will watch short videos of a stick figure moving. After each video, rate how natural "
        "the motion looks. Please watch every video to the end before you answer."))
    consent_text = models.TextField(default=(
        "This study is part of research on computer-generated motion. Taking part is voluntary and you "
        "may stop at any time. We record your ratings, the time you take, and the id your crowd "
        "platform gives you; nothing else about you."))
    language = models.CharField(
        max_length=8, choices=Language.choices, default=Language.ENGLISH,
        help_text="the language of the participant pages' own words (buttons, hints, messages); the title, "
                  "instructions, consent, question, labels and questions are shown as written")
    # A registered design's name (studyapp.designs.registry), as the ratings table's design column says it.
    design = models.CharField(max_length=20, choices=designs.choices, default=designs.DEFAULT)
    clips_per_participant = models.PositiveSmallIntegerField(
        default=20, help_text="single design: clips each participant rates, attention and instructed checks included",
        validators=[Within(1, 200, "one sitting")])
    ratings_per_stimulus = models.PositiveSmallIntegerField(
        default=10, help_text="target number of ratings of each stimulus", validators=[Within(1, 1000)])
    pages_per_participant = models.PositiveSmallIntegerField(
        default=8, help_text="side-by-side, pairwise and appropriateness: pages each participant answers, attention "
                             "and instructed checks included", validators=[Within(0, 100, "one sitting")])
    abx = models.BooleanField(
        default=False, help_text="pairwise: show the control's natural clip as the reference X above A and B, and ask "
                                 "which of them is closer to it (held-out controls only; NAT is then not paired)")
    preference_strengths = models.PositiveSmallIntegerField(
        default=0, help_text="pairwise: how many degrees of preference to ask (0: only which one; 2: GENEA's five "
                             "levels, slightly or clearly better either way, or none)",
        validators=[Within(0, 5, "a button each")])
    adaptive_pairing = models.BooleanField(
        default=False, help_text="pairwise: plan each new participant's pairs of systems where the votes so far leave "
                                 "the ranking least certain (a tenth of them at random), instead of evenly")
    reasons = models.TextField(
        blank=True, default="", validators=[reasons_problem],
        help_text="pairwise and side-by-side: the reasons a participant may tick for a page's answer, one a line "
                  "(GENEA asks: motion smoothness, recognisable gestures, unrealistic motion, amount of motion), "
                  "with an \"Other\" and its own words beside them; empty: no reasons asked")
    reasons_required = models.BooleanField(
        default=False, help_text="pairwise and side-by-side: a page's answer needs at least one reason (or "
                                 "\"Other\" with its words)")
    training_clips = models.PositiveSmallIntegerField(default=4, help_text="practice clips shown first and not recorded",
                                                      validators=[Within(0, 20)])
    bad_checks = models.PositiveSmallIntegerField(default=1, help_text="BAD clips per participant (attention checks)",
                                                  validators=[CHECKS])
    natural_checks = models.PositiveSmallIntegerField(
        default=1, help_text="NAT clips per participant placed as attention checks", validators=[CHECKS])
    bad_threshold = models.FloatField(
        default=4.0, help_text="on the 1-5 scale: rating a BAD clip this high or higher excludes", validators=[THRESHOLD])
    natural_threshold = models.FloatField(
        default=2.0, help_text="on the 1-5 scale: rating a NAT clip below this excludes", validators=[THRESHOLD])
    instructed_checks = models.PositiveSmallIntegerField(
        default=0, help_text="pages per participant, among their pages, that tell them which answer to give "
                             "(not analysed)", validators=[CHECKS])
    stop_after_failed_checks = models.PositiveSmallIntegerField(
        default=0, help_text="end a participant's session politely after this many failed instructed checks (0: never)",
        validators=[CHECKS])
    discard_early = models.BooleanField(default=True, help_text="flag ratings given before the clip finished playing")
    require_full_play = models.BooleanField(
        default=True, help_text="the rating buttons unlock when the clip has played to its end, and answers sent "
                                "sooner after the page than the clip lasts are refused")
    sliders_must_move = models.BooleanField(
        default=True, help_text="side-by-side: a page's answer is taken only once each of its sliders has been moved "
                                "(as webMUSHRA asks), so that no clip keeps the starting value unread")
    reservation_minutes = models.PositiveIntegerField(
        default=90, help_text="an unfinished participant's unrated clips stop counting towards the target after this idle time",
        validators=[Within(1, 7 * 24 * 60, "a week")])
    device_check = models.BooleanField(
        default=False, help_text="before consent, the browser plays a clip of the study and shows its screen size")
    min_screen_width = models.PositiveSmallIntegerField(default=0, help_text="CSS pixels the device check asks for (0: any)",
                                                        validators=[SCREEN_SIDE])
    min_screen_height = models.PositiveSmallIntegerField(default=0, help_text="CSS pixels the device check asks for (0: any)",
                                                         validators=[SCREEN_SIDE])
    platform = models.CharField(max_length=10, choices=Platform.choices, default=Platform.LINK)
    completion_code = models.CharField(max_length=100, blank=True)
    # Participants who do not finish the ratings still leave with a code of their own, so
    # the platform pays them as its rules say (Prolific: a fixed screen-out payment) and
    # the researcher sees why they stopped, instead of being asked to return the study.
    screen_out_code = models.CharField(
        max_length=100, blank=True, help_text="given to participants a screening question turns away (Prolific: a "
                                              "code of type 'screened out' with its fixed payment; empty: they are "
                                              "asked to return the study)")
    stopped_code = models.CharField(
        max_length=100, blank=True, help_text="given to participants stopped after failed instructed checks (empty: "
                                              "they are asked to return the study)")
    redirect_url = models.URLField(blank=True, help_text="where finished participants are sent (Prolific: its completion URL)")
    camera = models.JSONField(default=default_camera, validators=[storable_json])
    # The display figure every clip is drawn on: the reference skeleton's bone lengths
    # (``generation.render.display_figure``), set when the stimuli are planned.
    display_figure = models.JSONField(default=dict, blank=True, validators=[storable_json, display_figure_problem])
    video_width = models.PositiveSmallIntegerField(default=640, validators=[VIDEO_SIDE])
    video_height = models.PositiveSmallIntegerField(default=480, validators=[VIDEO_SIDE])
    path_tolerance_cm = models.FloatField(
        default=PATH_TOLERANCE_CM, validators=[Within(1, 100_000, "cm")],
        help_text="submitted motion: how far (cm) a clip's root may stray from its path control's path; raise it for "
                  "motion that need not follow the controls (another lab's natural motion, a model whose path differs)")
    expected_effect = models.FloatField(
        null=True, blank=True, validators=[Within(0, 5, "a standardised difference or a share")],
        help_text="the smallest effect the study should detect (the design says in what terms: a standardised "
                  "difference of means, or the share of pages preferring the better system); given, the plan "
                  "locked at opening takes its participants from the power of the design's test (empty: from "
                  "the targets)")
    is_open = models.BooleanField(default=False, help_text="accepting participants")
    previewed_at = models.DateTimeField(null=True, blank=True, help_text="when the researcher last saw the preview")
    created = models.DateTimeField(auto_now_add=True)
    # Participant pages keep the study in memory while this stamp is unchanged (``study_cache``).
    updated = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["-created"]
        verbose_name_plural = "studies"

    def __str__(self) -> str:
        return self.title

    def save(self, *args, **kwargs) -> None:
        """Save, stamping ``updated`` even when only some fields are saved (``update_fields``)."""
        if kwargs.get("update_fields") is not None:
            kwargs["update_fields"] = {*kwargs["update_fields"], "updated"}
        elif not self.display_figure and self.pk is not None:
            # Planning works the display figure out and stores it by an update, so an instance
            # loaded before (a settings page, a script) still holds none: saving it must not wipe
            # the figure that every planned clip's content key digests.
            stored = Study.objects.filter(pk=self.pk).values_list("display_figure", flat=True).first()
            self.display_figure = stored or self.display_figure
        super().save(*args, **kwargs)

    def clean(self) -> None:
        if self.scale_min >= self.scale_max:
            raise ValidationError({"scale_max": f"the scale must rise: {self.scale_min} to {self.scale_max} does not"})
        if self.video_width % 2 or self.video_height % 2:
            raise ValidationError({"video_width": "H.264 video needs an even width and height"})
        if self.video_width * self.video_height > MAX_VIDEO_PIXELS:
            raise ValidationError({"video_width": f"{self.video_width}×{self.video_height} is past 4K video: at most "
                                                  f"{MAX_VIDEO_PIXELS:,} pixels a frame (3840×2160)"})
        try:
            design = designs.design_of(self)
        except KeyError as unknown:
            raise ValidationError({"design": unknown.args[0]}) from None
        if problems := design.problems(self):
            raise ValidationError(problems)
        for name, owners in designs.foreign_settings(self.design).items():
            # A switch of another design's, turned on (one that is on unless turned off, as
            # side-by-side's sliders_must_move, does nothing in the designs that do not read it).
            if getattr(self, name) is True and self._meta.get_field(name).default is not True:
                raise ValidationError({name: f"{self._meta.get_field(name).verbose_name} goes with the "
                                             f"{' or '.join(owners)} design"})
        if self.reason_list and (owners := designs.foreign_settings(self.design).get("reasons")):
            raise ValidationError({"reasons": f"reasons go with the {' or '.join(owners)} design"})
        if self.stop_after_failed_checks > self.instructed_checks:
            raise ValidationError({"stop_after_failed_checks": f"a participant meets {self.instructed_checks} "
                                                               f"instructed check(s): stopping after "
                                                               f"{self.stop_after_failed_checks} failed never happens"})
        if self.expected_effect is not None:  # in the terms of the design's test, which checks its range
            try:
                analysed_design(self.design).planned_units(self.expected_effect, 2, ALPHA, POWER)
            except ValueError as error:
                raise ValidationError({"expected_effect": str(error)}) from None
        problem = camera_problem(self.camera)
        if problem:  # not keyed to "camera": the study form shows the camera as one field per setting
            raise ValidationError(f"camera: not a camera description: {problem}")

    @property
    def scale(self) -> range:
        return range(self.scale_min, self.scale_max + 1)

    @property
    def strengths(self) -> range:
        return range(1, self.preference_strengths + 1)

    @property
    def reason_list(self) -> list[str]:
        """The reasons a page asks for (empty: none), as the participant reads them."""
        return reason_lines(self.reasons)


# Past 10 the noise swamps what a model learnt; the models take any finite temperature.
TEMPERATURE = Within(0.0001, 10, "the sampling temperature")


class System(models.Model):
    """A condition of the study: a trained model, natural motion (NAT) or attention checks (BAD)."""

    class Role(models.TextChoices):
        MODEL = "model", "model"
        NATURAL = "natural", "natural motion (NAT)"
        BAD = "bad", "attention check (BAD)"

    class SourceKind(models.TextChoices):
        """Where the motion comes from (``studyapp.stimuli.sources``); apart from checkpoints, the ``kind`` field."""
        CHECKPOINT = "checkpoint", "model checkpoint"
        NATURAL = "natural", "natural clips"
        SUBMITTED = "submitted", "submitted motion"
        VIDEO = "video", "uploaded videos"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="systems")
    name = models.CharField(max_length=60)
    role = models.CharField(max_length=10, choices=Role.choices, default=Role.MODEL)
    # Relative to settings.CHECKPOINT_ROOT, named by content digest; empty for NAT and uploaded videos.
    checkpoint = models.CharField(max_length=200, blank=True)
    checkpoint_digest = models.CharField(max_length=64, blank=True)
    kind = models.CharField(max_length=30, blank=True)
    metadata = models.JSONField(default=dict, blank=True, validators=[storable_json])
    # The researcher's corrections of how the rig's joints map to the display figure's
    # points (point -> joint name), over the mapping found from the rig (``stimuli.figure``).
    figure_mapping = models.JSONField(default=dict, blank=True, validators=[storable_json, figure_mapping_problem])
    temperature = models.FloatField(default=1.0, validators=[TEMPERATURE])
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["study", "role", "name"]
        constraints = [models.UniqueConstraint(fields=["study", "name"], name="unique_system_name")]

    def __str__(self) -> str:
        return f"{self.name} ({self.get_role_display()})"

    @property
    def export_name(self) -> str:
        """The name in the ratings table: NAT and BAD for their roles, so the analysis finds them."""
        return export_name(self.role, self.name)

    @property
    def source_kind(self) -> str:
        """A ``SourceKind``: a checkpoint system's ``kind`` names its model kind instead."""
        return self.SourceKind.CHECKPOINT if self.checkpoint else self.kind

    def checkpoint_path(self) -> Path | None:
        return Path(settings.CHECKPOINT_ROOT) / self.checkpoint if self.checkpoint else None

    # What a checkpoint system's metadata tells the study (``systems.checkpoint_metadata``
    # writes it); each reader raises StoredDataError naming the system if it cannot.

    def dataset_options(self) -> DatasetOptions:
        """The options of the data the checkpoint was trained on."""
        data = json_object(self, "metadata").get("dataset_options")
        try:
            return DatasetOptions.from_dict(data)
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise StoredDataError(self, "metadata", f"holds no readable dataset_options ({error!r})") from None

    def labels(self) -> dict[str, list[str]] | None:
        """The actions and styles a label-controlled checkpoint knows (None for a path-controlled one)."""
        labels = json_object(self, "metadata").get("labels")
        if not labels:
            return None
        if not (isinstance(labels, dict) and all(isinstance(labels.get(part), list) and
                                                 all(isinstance(name, str) for name in labels[part])
                                                 for part in ("actions", "styles"))):
            raise StoredDataError(self, "metadata", "holds labels that are not lists of actions and styles")
        return labels

    def clean(self) -> None:
        if self.source_kind not in self.SourceKind.values:
            kinds = [kind for kind in self.SourceKind.values if kind != self.SourceKind.CHECKPOINT]
            raise ValidationError({"kind": f"a system without a checkpoint has its motion from {', '.join(kinds)}, "
                                           f"not {self.kind!r}"})
        try:
            json_object(self, "metadata")
            if self.checkpoint:  # every reader of a checkpoint's metadata can read it
                self.dataset_options()
                self.labels()
        except StoredDataError as error:
            raise ValidationError({"metadata": str(error)}) from None


def export_name(role: str, name: str) -> str:
    """The name in the ratings table of a system of ``role`` called ``name``."""
    return {System.Role.NATURAL: NATURAL_NAME, System.Role.BAD: ATTENTION_NAME}.get(role, name)


class ControlSignal(models.Model):
    """A control signal every model system is sampled with: held out from real clips, or synthetic."""

    class Origin(models.TextChoices):
        HELD_OUT = "held-out", "held-out"
        SYNTHETIC = "synthetic", "synthetic"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="controls")
    name = models.CharField(max_length=100)
    origin = models.CharField(max_length=10, choices=Origin.choices)
    control = models.JSONField(help_text="generation.control's to_dict() form", validators=[storable_json])
    # For held-out control: the natural clip it came from, which NAT stimuli show.
    source_clip = models.CharField(max_length=200, blank=True)
    # For held-out control: where its take was found and how it is read (``stimuli.natural.NaturalSource``).
    natural = models.JSONField(default=dict, blank=True, validators=[storable_json],
                               help_text="held-out: the folders its take was found in and the dataset options it is "
                                         "read with")
    seconds = models.FloatField()
    # The name other labs' files carry (``control_export.control_id``): the name the control
    # was created with, kept when it is renamed, so exported controls and submitted motion
    # stay matched; empty where that name was no plain file name (then control-<pk>).
    export_id = models.CharField(max_length=100, blank=True, editable=False)

    class Meta:
        ordering = ["study", "origin", "name"]
        constraints = [models.UniqueConstraint(fields=["study", "name"], name="unique_control_name")]

    def __str__(self) -> str:
        return f"{self.name} ({self.origin})"

    def signal(self) -> Control:
        """The stored control as ``generation.control`` reads it (StoredDataError if it is none)."""
        try:
            return control_from_dict(json_object(self, "control"))
        except StoredDataError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as error:
            detail = f"lacks {error}" if isinstance(error, KeyError) else str(error)
            raise StoredDataError(self, "control", f"is no control description ({detail})") from None

    def recorded_options(self) -> DatasetOptions | None:
        """The dataset options a held-out control's take was read with, as recorded when it
        was added (None where none were: controls made before they were recorded)."""
        if not self.natural:
            return None
        try:
            return DatasetOptions.from_dict(json_object(self, "natural")["options"])
        except StoredDataError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            raise StoredDataError(self, "natural", f"holds no readable dataset options ({error!r})") from None

    def save(self, *args, **kwargs) -> None:
        """Save, giving a new control its export id: its name, unless that is no plain file
        name or another control of the study (since renamed) already has it."""
        if self._state.adding and not self.export_id and SAFE_ID.fullmatch(self.name):
            taken = ControlSignal.objects.filter(study_id=self.study_id, export_id=self.name).exists()
            self.export_id = "" if taken else self.name
        super().save(*args, **kwargs)

    @property
    def lead_in_seconds(self) -> float:
        """How far into its take a held-out control starts: the length of its lead-in (0 without one)."""
        signal = self.signal()
        return len(signal.lead_in) / signal.fps if getattr(signal, "lead_in", None) is not None else 0.0

    @property
    def problem(self) -> str:
        """Why the stored control cannot be read ("" when it can), for the pages that list controls."""
        try:
            self.signal()
        except StoredDataError as error:
            return str(error)
        return ""

    def clean(self) -> None:
        if problem := self.problem:
            raise ValidationError({"control": problem})


class Stimulus(models.Model):
    """One clip: a system's motion for a control signal, rendered with the study's camera.

    ``content_key`` digests everything the clip depends on, so generating again finds the
    existing row instead of making a second one.
    """

    class Status(models.TextChoices):
        PENDING = "pending", "not queued"
        QUEUED = "queued", "queued"
        RUNNING = "running", "running"
        DONE = "done", "done"
        FAILED = "failed", "failed"

    # ``seed`` is a 32-bit column, which PostgreSQL enforces (SQLite would store more).
    MAX_SEED = 2**31 - 1

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="stimuli")
    system = models.ForeignKey(System, on_delete=models.CASCADE, related_name="stimuli")
    control = models.ForeignKey(ControlSignal, on_delete=models.CASCADE, related_name="stimuli", null=True, blank=True)
    # An appropriateness study's mismatched clip: the system's motion for ``control``, shown
    # (and drawn over the path of) this other control, whose page it appears on.
    shown_control = models.ForeignKey(
        ControlSignal, on_delete=models.CASCADE, related_name="mismatched_stimuli", null=True, blank=True,
        help_text="appropriateness: the control a page shows this clip of another control against (empty: its own)")
    seed = models.IntegerField(default=0)
    content_key = models.CharField(max_length=64)
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    status = models.CharField(max_length=10, choices=Status.choices, default=Status.PENDING)
    error = models.TextField(blank=True)
    attempts = models.PositiveSmallIntegerField(default=0)
    task_id = models.CharField(max_length=64, blank=True)
    duration_s = models.FloatField(null=True, blank=True)
    updated = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["study", "system", "control"]
        verbose_name_plural = "stimuli"
        constraints = [models.UniqueConstraint(fields=["study", "content_key"], name="unique_stimulus_content")]

    def __str__(self) -> str:
        return f"{self.system.name} / {self.control.name if self.control else 'uploaded video'} [{self.status}]"

    @property
    def relative_path(self) -> str:
        return f"stimuli/{self.token}.mp4"

    def video_path(self) -> Path:
        return Path(settings.MEDIA_ROOT) / self.relative_path

    @property
    def video_url(self) -> str:
        if in_bucket():  # the bucket's own expiring address (studyapp.server.bucket_addresses)
            return presigned_clip_url(self.relative_path)
        if settings.MEDIA_ACCEL:  # behind the proxy: an address that expires (studyapp.server.clip_urls)
            return signed_clip_url(self.relative_path)
        return f"/{settings.MEDIA_URL.strip('/')}/{self.relative_path}"

    @property
    def control_class(self) -> str:
        return self.control.origin if self.control else "uploaded"


class Participant(models.Model):
    """One person's pass through a study, identified by their crowd platform's id."""

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="participants")
    platform_id = models.CharField(max_length=100)
    platform_data = models.JSONField(default=dict, blank=True, validators=[storable_json])
    # Anonymous id written to the ratings table instead of the platform id.
    code = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    started_at = models.DateTimeField(auto_now_add=True)
    last_seen = models.DateTimeField(auto_now_add=True)
    consented_at = models.DateTimeField(null=True, blank=True)
    instructed_at = models.DateTimeField(null=True, blank=True)
    training = models.JSONField(default=list, blank=True, help_text="ids of the practice stimuli, in order",
                                validators=[storable_json])
    training_done = models.PositiveSmallIntegerField(default=0)
    finished_at = models.DateTimeField(null=True, blank=True)
    failed_checks = models.PositiveSmallIntegerField(default=0, help_text="instructed checks answered otherwise than asked")
    # Set with finished_at when failed_checks reaches the study's stop_after_failed_checks.
    stopped_at = models.DateTimeField(null=True, blank=True)
    device_checked_at = models.DateTimeField(null=True, blank=True)
    screened_at = models.DateTimeField(null=True, blank=True, help_text="passed the questions before the ratings")
    screened_out_at = models.DateTimeField(null=True, blank=True, help_text="a screening answer did not match")
    surveyed_at = models.DateTimeField(null=True, blank=True, help_text="answered the questions after the ratings")
    answers = models.JSONField(default=dict, blank=True, help_text="questionnaire answers by question name",
                               validators=[storable_json])
    excluded = models.BooleanField(default=False)
    exclusion_reason = models.CharField(max_length=100, blank=True)
    # Answers refused for coming sooner than the clip lasts (require_full_play): they are
    # not ratings, so only this count keeps them for the researcher.
    refused_early = models.PositiveSmallIntegerField(default=0)
    user_agent = models.CharField(max_length=300, blank=True)

    class Meta:
        ordering = ["study", "started_at"]
        constraints = [models.UniqueConstraint(fields=["study", "platform_id"], name="one_start_per_platform_id")]

    def __str__(self) -> str:
        return f"{self.platform_id} in {self.study}"

    def practice_ids(self) -> list[int]:
        """The ids of the practice stimuli, in order (StoredDataError if ``training`` holds anything else)."""
        if not (isinstance(self.training, list) and all(type(pk) is int for pk in self.training)):
            raise StoredDataError(self, "training", "must be a JSON list of stimulus ids")
        return self.training

    def clean(self) -> None:
        for field in ("answers", "platform_data"):
            if not isinstance(getattr(self, field), dict):
                raise ValidationError({field: "must be a JSON object"})
        try:
            self.practice_ids()
        except StoredDataError:
            raise ValidationError({"training": "must be a JSON list of stimulus ids"}) from None


ANSWER_BOUND = Within(-1e9, 1e9, "a number a participant types")


class Question(models.Model):
    """A question asked before the ratings (screening: other answers than the accepted
    ones end the study politely) or after them (demographics, comments)."""

    class Part(models.TextChoices):
        BEFORE = "before", "before the ratings (screening)"
        AFTER = "after", "after the ratings"

    class Kind(models.TextChoices):
        CHOICE = "choice", "one of several choices"
        NUMBER = "number", "a number"
        TEXT = "text", "free text"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="questions")
    part = models.CharField(max_length=10, choices=Part.choices)
    name = models.SlugField(max_length=40, help_text="its column in the participant list")
    text = models.CharField(max_length=300)
    kind = models.CharField(max_length=10, choices=Kind.choices, default=Kind.CHOICE)
    choices = models.TextField(blank=True, help_text="one per line (choice questions)")
    accepted = models.TextField(blank=True, help_text="before the ratings: the choices that may go on, one per line "
                                                      "(empty: every answer)")
    required = models.BooleanField(default=True)
    # Number questions' answers lie in [minimum, maximum]; the defaults suit an age in years.
    minimum = models.FloatField(default=0, validators=[ANSWER_BOUND], help_text="number questions: the smallest answer")
    maximum = models.FloatField(default=120, validators=[ANSWER_BOUND], help_text="number questions: the largest answer")
    whole_numbers = models.BooleanField(default=True, help_text="number questions: only whole numbers (as ages)")
    order = models.PositiveSmallIntegerField(default=0, help_text="its place among the questions of its part")
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["study", "part", "order", "created", "pk"]
        constraints = [models.UniqueConstraint(fields=["study", "name"], name="unique_question_name")]

    def __str__(self) -> str:
        return self.text

    @property
    def choice_list(self) -> list[str]:
        return [line.strip() for line in self.choices.splitlines() if line.strip()]

    @property
    def accepted_list(self) -> list[str]:
        return [line.strip() for line in self.accepted.splitlines() if line.strip()]

    def clean(self) -> None:
        if self.kind == self.Kind.CHOICE and len(self.choice_list) < 2:
            raise ValidationError({"choices": "a choice question needs at least two choices, one per line"})
        if self.kind != self.Kind.CHOICE and (self.choices.strip() or self.accepted.strip()):
            raise ValidationError({"choices": "only choice questions have choices"})
        if unknown := [a for a in self.accepted_list if a not in self.choice_list]:
            raise ValidationError({"accepted": f"not among the choices: {', '.join(unknown)}"})
        if self.accepted_list and self.part != self.Part.BEFORE:
            raise ValidationError({"accepted": "only questions before the ratings screen participants"})
        if self.kind == self.Kind.NUMBER and not self.minimum < self.maximum:
            raise ValidationError({"maximum": f"the largest answer must exceed the smallest ({self.minimum:g})"})
        if self.kind == self.Kind.NUMBER and self.whole_numbers and math.floor(self.maximum) < self.minimum:
            raise ValidationError({"maximum": f"no whole number lies from {self.minimum:g} to {self.maximum:g}"})


class Assignment(models.Model):
    """A clip placed at a position in a participant's sequence, on one of their pages.

    A page shows one clip (single design), K clips at slots 1..K (side-by-side) or two at
    slots 1 (left) and 2 (right) (pairwise); the clips of a page are answered together.
    """

    LEFT, RIGHT = 1, 2  # a pairwise page's slots

    participant = models.ForeignKey(Participant, on_delete=models.CASCADE, related_name="assignments")
    stimulus = models.ForeignKey(Stimulus, on_delete=models.PROTECT, related_name="assignments")
    position = models.PositiveSmallIntegerField()
    page = models.PositiveSmallIntegerField(default=0)
    slot = models.PositiveSmallIntegerField(default=1, help_text="where on its page, from 1 (pairwise: 1 left, 2 right)")
    is_check = models.BooleanField(default=False, help_text="placed as an attention check")
    # An instructed check: the answer its page asks for ("" on every other page). Its
    # clips repeat others the participant sees, and its answers are not exported. (A
    # clip may also be on several pairwise pages of one participant, so no constraint
    # keeps clips unique per participant; the single design's plan never repeats one.)
    expected = models.CharField(max_length=10, blank=True)
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    shown_at = models.DateTimeField(
        null=True, blank=True,
        help_text="when the server first sent its page, or the answer to the clip before it, which leads there")

    class Meta:
        ordering = ["participant", "position"]
        constraints = [
            models.UniqueConstraint(fields=["participant", "position"], name="one_clip_per_position"),
            models.UniqueConstraint(fields=["participant", "page", "slot"], name="one_clip_per_slot"),
        ]


class Rating(models.Model):
    """A participant's answer to one assignment, with the timings that judge it."""

    class Answer(models.TextChoices):  # a pairwise page's answer, the same on both its ratings
        LEFT = "left", "left"
        RIGHT = "right", "right"
        NONE = "none", "no preference"

    assignment = models.OneToOneField(Assignment, on_delete=models.CASCADE, related_name="rating")
    value = models.SmallIntegerField(null=True, blank=True, help_text="on the study's scale; none on pairwise pages")
    answer = models.CharField(max_length=5, choices=Answer.choices, blank=True)
    strength = models.PositiveSmallIntegerField(null=True, blank=True)
    answered_at = models.DateTimeField(auto_now_add=True)
    # Client-side times in seconds after the page was shown (None: the event never happened).
    client_started_s = models.FloatField(null=True, blank=True)
    client_ended_s = models.FloatField(null=True, blank=True)
    client_answered_s = models.FloatField(null=True, blank=True)
    played_until_s = models.FloatField(null=True, blank=True)
    answered_before_end = models.BooleanField(default=False)
    # The reasons ticked for the page's answer (the study's words), the same on every rating of the page.
    reasons = models.JSONField(default=list, blank=True)
    other_reason = models.CharField(max_length=300, blank=True, default="",
                                    help_text="the participant's own words under \"Other\" (plain text)")

    class Meta:
        ordering = ["answered_at"]


class PlatformAction(models.Model):
    """One request sent to a crowd platform's API for a study (``studyapp.platforms``): the
    log of what was approved, rejected, asked back or paid, and the record that makes a
    retry send only what has not been done.

    ``key`` names what the request does to whom (``approve:<submission>``); a key with a
    ``done`` row is never sent again. The request is kept as it was sent, never with the
    researcher's credentials.
    """

    class Outcome(models.TextChoices):
        DONE = "done", "done"
        FAILED = "failed", "failed"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="platform_actions")
    participant = models.ForeignKey(Participant, on_delete=models.SET_NULL, null=True, blank=True,
                                    related_name="platform_actions")
    researcher = models.ForeignKey(settings.AUTH_USER_MODEL, on_delete=models.SET_NULL, null=True, blank=True)
    platform = models.CharField(max_length=10, choices=Study.Platform.choices)
    key = models.CharField(max_length=200)
    action = models.CharField(max_length=30)
    request = models.JSONField(help_text="what was sent: method or operation, address, body")
    outcome = models.CharField(max_length=10, choices=Outcome.choices)
    response = models.JSONField(default=dict, blank=True, help_text="the platform's answer, or its error")
    sent_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["study", "sent_at", "pk"]
        constraints = [models.UniqueConstraint(fields=["study", "key"], condition=models.Q(outcome="done"),
                                               name="one_done_platform_action_per_key")]

    def __str__(self) -> str:
        return f"{self.action} {self.key} [{self.outcome}]"


class ImmutableRow(ValueError):
    """A row that is written once (a locked plan) was asked to change."""


class StudyPlan(models.Model):
    """A study's plan as it stood when the study first opened (``studyapp.preregistration``): its
    design and settings, rules, systems, controls, planned analysis and number of
    participants, as canonical JSON with its SHA-256. Written once: reopening a closed
    study keeps it, and every later change is a ``PlanDeviation``."""

    study = models.OneToOneField(Study, on_delete=models.CASCADE, related_name="plan")
    canonical = models.TextField(help_text="the plan as canonical JSON (sorted keys, no spaces, UTF-8)")
    sha256 = models.CharField(max_length=64, help_text="SHA-256 of the canonical JSON's UTF-8 bytes")
    locked_at = models.DateTimeField()

    def __str__(self) -> str:
        return f"plan of {self.study} ({self.sha256[:12]}, {self.locked_at:%Y-%m-%d %H:%M})"

    def save(self, *args, **kwargs) -> None:
        if not self._state.adding:
            raise ImmutableRow(f"the plan of study {self.study_id} is locked: it is written once")
        super().save(*args, **kwargs)


class PlanDeviation(models.Model):
    """One change to a locked plan: which part of it (``field``, as ``studyapp.preregistration``
    names it), its value before and after (None: absent), and when. Written once."""

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="plan_deviations")
    at = models.DateTimeField()
    field = models.CharField(max_length=200)
    old = models.JSONField(null=True)
    new = models.JSONField(null=True)

    class Meta:
        ordering = ["study", "at", "pk"]

    def __str__(self) -> str:
        return f"{self.field}: {self.old!r} -> {self.new!r}"

    def save(self, *args, **kwargs) -> None:
        if not self._state.adding:
            raise ImmutableRow(f"deviation {self.pk} of study {self.study_id} is recorded: it is written once")
        super().save(*args, **kwargs)


class PreviousRun(models.Model):
    """The ratings of the study a rerun was imported from (``studyapp.bundles``): its ratings
    table and rules as its bundle held them, which the rerun's report compares with its own."""

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="previous_runs")
    ratings_csv = models.TextField(help_text="the previous study's ratings table (docs/ratings-schema.md)")
    rules_json = models.TextField(help_text="the rules it was collected under, as the analysis reads them")
    code_version = models.CharField(max_length=100, blank=True, help_text="the code that exported it")
    imported_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["study", "imported_at", "pk"]

    def __str__(self) -> str:
        return f"previous run of {self.study}"


# The leaderboards that span studies live in their own room; Django finds their models here.
from studyapp.leaderboards.models import Leaderboard, Round  # noqa: E402,F401
