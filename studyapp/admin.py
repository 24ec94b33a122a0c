"""Django admin for every model of the study app; the study pages are the main interface.

A researcher who is staff sees and writes only the rows of their own studies, as on the
study pages: a new study is theirs (the owner comes from the request, so the form never
lists other researchers' names); a superuser sees everything. The names a row holds of
files and folders (a held-out control's take and folders, a submitted system's folder)
point only at the study owner's own or at what is shared (``studyapp.ownership``). What
a study that has begun keeps fixed (``studyapp.preregistration.fixed``) is refused here as on the
study's pages, and what it allows is recorded as a deviation from its plan, as on every
path (``studyapp.preregistration.lock``).
"""

from django import forms
from django.contrib import admin, messages
from django.core.exceptions import ValidationError
from django.db import models

from studyapp.models import Assignment, ControlSignal, Participant, Rating, Stimulus, Study, System
from studyapp.ownership import NotYours, check_take
from studyapp.preregistration.fixed import change_refusal, deletion_refusal
from studyapp.researchers.setup.removal import remove_study
from studyapp.stimuli.submissions import SUBMITTED_FOLDER


class ReadableJSONField(forms.JSONField):
    """Django's JSON form field, refusing JSON nested too deeply for the parser to read:
    thousands of brackets exhaust its stack, which Django would answer with a 500."""

    NESTED = "nested too deeply to read"

    def to_python(self, value):
        try:
            return super().to_python(value)
        except RecursionError:
            raise ValidationError(self.NESTED, code="invalid") from None

    def bound_data(self, data, initial):
        try:
            return super().bound_data(data, initial)
        except RecursionError:  # shown again as typed, beside the error
            return forms.fields.InvalidJSONInput(data)


# The fields that tie a row to its study, directly or through a participant's page.
LINKS = ("study", "participant", "assignment")


class PlanLockedForm(forms.ModelForm):
    """A row's admin form, refusing what a study that has begun keeps fixed (``plan.fixed``),
    as the study's pages and commands refuse it."""

    def clean(self):
        cleaned = super().clean()
        row = self.instance
        if row.pk is None:  # the study it is added to, as the form gives it
            row = self._meta.model(**{name: cleaned[name] for name in LINKS if cleaned.get(name) is not None},
                                   **({"seed": cleaned["seed"]} if "seed" in cleaned else {}))
        if (refusal := change_refusal(row, self.changed_data)) is not None:
            raise ValidationError(refusal)
        return cleaned


class OwnStudiesOnly(admin.ModelAdmin):
    """Rows (and the choices in foreign-key fields) limited to the user's own studies.

    ``owner_path`` is the lookup from this model to the study's owner. What a study that
    has begun keeps fixed (``plan.fixed``) is refused on change, on adding and on deletion.
    """

    owner_path = "study__owner"
    form = PlanLockedForm
    formfield_overrides = {models.JSONField: {"form_class": ReadableJSONField}}

    def has_delete_permission(self, request, obj=None):
        return super().has_delete_permission(request, obj) and (obj is None or deletion_refusal(obj) is None)

    def delete_queryset(self, request, queryset):
        refusals = [refusal for row in queryset if (refusal := deletion_refusal(row)) is not None]
        if refusals:
            self.message_user(request, f"Nothing deleted: {refusals[0]}", messages.ERROR)
            return
        super().delete_queryset(request, queryset)

    def get_queryset(self, request):
        rows = super().get_queryset(request)
        return rows if request.user.is_superuser else rows.filter(**{self.owner_path: request.user})

    def formfield_for_foreignkey(self, db_field, request, **kwargs):
        field = super().formfield_for_foreignkey(db_field, request, **kwargs)
        related = db_field.related_model
        if not request.user.is_superuser and related in OWNER_PATHS:
            field.queryset = field.queryset.filter(**{OWNER_PATHS[related]: request.user})
        return field


# From each model to the owner of its study.
OWNER_PATHS = {Study: "owner", System: "study__owner", ControlSignal: "study__owner", Stimulus: "study__owner",
               Participant: "study__owner", Assignment: "participant__study__owner",
               Rating: "assignment__participant__study__owner"}


@admin.register(Study)
class StudyAdmin(OwnStudiesOnly):
    owner_path = OWNER_PATHS[Study]
    list_display = ["title", "owner", "design", "scale_min", "scale_max", "platform", "is_open", "created"]
    list_filter = ["is_open", "platform"]
    search_fields = ["title"]
    readonly_fields = ["key", "created"]

    def get_exclude(self, request, obj=None):
        excluded = list(super().get_exclude(request, obj) or [])
        return excluded if request.user.is_superuser else [*excluded, "owner"]

    def save_model(self, request, obj, form, change):
        if not change and not request.user.is_superuser:
            obj.owner = request.user
        super().save_model(request, obj, form, change)

    # A deleted study takes its clips' files along (``removal.remove_study``).
    def delete_model(self, request, obj):
        remove_study(obj)

    def delete_queryset(self, request, queryset):
        for study in queryset:
            remove_study(study)


class SystemForm(PlanLockedForm):
    """Submitted motion is read from the folder named by the system's digest, which the admin
    does not change: another folder would be another researcher's motion."""

    def clean(self):
        cleaned = super().clean()
        metadata, folder = cleaned.get("metadata"), f"{SUBMITTED_FOLDER}/{self.instance.checkpoint_digest}"
        if cleaned.get("kind") == System.SourceKind.SUBMITTED and isinstance(metadata, dict) \
                and metadata.get("folder") != folder:
            raise ValidationError(f"submitted motion lies in the folder named by its digest: its metadata's folder "
                                  f"must be {folder!r}")
        return cleaned


@admin.register(System)
class SystemAdmin(OwnStudiesOnly):
    form = SystemForm
    list_display = ["name", "study", "role", "kind", "temperature"]
    list_filter = ["role"]
    readonly_fields = ["checkpoint", "checkpoint_digest", "created"]


class ControlSignalForm(PlanLockedForm):
    """A held-out take and its folders are names: of the study owner's own, or shared."""

    def clean(self):
        cleaned = super().clean()
        if (study := cleaned.get("study")) is not None:
            try:
                check_take(study.owner, cleaned.get("source_clip") or "", cleaned.get("natural"))
            except NotYours as error:
                raise ValidationError(str(error)) from None
        return cleaned


@admin.register(ControlSignal)
class ControlSignalAdmin(OwnStudiesOnly):
    form = ControlSignalForm
    list_display = ["name", "study", "origin", "seconds", "source_clip"]
    list_filter = ["origin"]


@admin.register(Stimulus)
class StimulusAdmin(OwnStudiesOnly):
    list_display = ["token", "study", "system", "control", "status", "attempts", "duration_s", "updated"]
    list_filter = ["status"]
    readonly_fields = ["token", "content_key", "task_id", "updated"]


@admin.register(Participant)
class ParticipantAdmin(OwnStudiesOnly):
    list_display = ["platform_id", "study", "started_at", "finished_at", "excluded", "exclusion_reason", "failed_checks",
                    "stopped_at"]
    list_filter = ["excluded"]
    search_fields = ["platform_id", "code"]
    readonly_fields = ["code", "started_at"]


@admin.register(Assignment)
class AssignmentAdmin(OwnStudiesOnly):
    owner_path = OWNER_PATHS[Assignment]
    list_display = ["participant", "position", "page", "slot", "stimulus", "is_check", "expected", "shown_at"]
    list_filter = ["is_check"]
    readonly_fields = ["token"]


@admin.register(Rating)
class RatingAdmin(OwnStudiesOnly):
    owner_path = OWNER_PATHS[Rating]
    list_display = ["assignment", "value", "answer", "strength", "answered_at", "answered_before_end"]
    list_filter = ["answered_before_end"]
    readonly_fields = ["answered_at"]


# The leaderboards' admin, in their own room.
import studyapp.leaderboards.admin  # noqa: E402,F401
