"""Django admin for every model of the study app; the study pages are the main interface."""

from django.contrib import admin

from studyapp.models import Assignment, ControlSignal, Participant, Rating, Stimulus, Study, System


@admin.register(Study)
class StudyAdmin(admin.ModelAdmin):
    list_display = ["title", "owner", "scale_min", "scale_max", "platform", "is_open", "created"]
    list_filter = ["is_open", "platform"]
    search_fields = ["title"]
    readonly_fields = ["key", "created"]


@admin.register(System)
class SystemAdmin(admin.ModelAdmin):
    list_display = ["name", "study", "role", "kind", "temperature"]
    list_filter = ["role", "study"]
    readonly_fields = ["checkpoint", "checkpoint_digest", "created"]


@admin.register(ControlSignal)
class ControlSignalAdmin(admin.ModelAdmin):
    list_display = ["name", "study", "origin", "seconds", "source_clip"]
    list_filter = ["origin", "study"]


@admin.register(Stimulus)
class StimulusAdmin(admin.ModelAdmin):
    list_display = ["token", "study", "system", "control", "status", "attempts", "duration_s", "updated"]
    list_filter = ["status", "study", "system"]
    readonly_fields = ["token", "content_key", "task_id", "updated"]


@admin.register(Participant)
class ParticipantAdmin(admin.ModelAdmin):
    list_display = ["platform_id", "study", "started_at", "finished_at", "excluded", "exclusion_reason"]
    list_filter = ["excluded", "study"]
    search_fields = ["platform_id", "code"]
    readonly_fields = ["code", "started_at"]


@admin.register(Assignment)
class AssignmentAdmin(admin.ModelAdmin):
    list_display = ["participant", "position", "stimulus", "is_check", "shown_at"]
    list_filter = ["is_check"]
    readonly_fields = ["token"]


@admin.register(Rating)
class RatingAdmin(admin.ModelAdmin):
    list_display = ["assignment", "value", "answered_at", "answered_before_end"]
    list_filter = ["answered_before_end"]
    readonly_fields = ["answered_at"]
