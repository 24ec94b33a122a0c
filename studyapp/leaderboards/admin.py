"""The admin of leaderboards: each researcher's own boards only, their rounds their own studies."""

from __future__ import annotations

from django.contrib import admin

from studyapp.leaderboards.forms import AdminRoundForm, AdminRoundFormSet
from studyapp.leaderboards.models import Leaderboard, Round


class RoundInline(admin.TabularInline):
    model = Round
    form = AdminRoundForm
    formset = AdminRoundFormSet
    extra = 0
    fields = ["study", "in_fit", "left_out_because", "added"]
    readonly_fields = ["added"]

    def formfield_for_foreignkey(self, db_field, request, **kwargs):
        field = super().formfield_for_foreignkey(db_field, request, **kwargs)
        if db_field.name == "study" and not request.user.is_superuser:
            field.queryset = field.queryset.filter(owner=request.user, design="pairwise")
        return field


@admin.register(Leaderboard)
class LeaderboardAdmin(admin.ModelAdmin):
    list_display = ["title", "owner", "public", "created"]
    readonly_fields = ["public_key", "created"]
    inlines = [RoundInline]

    def get_queryset(self, request):
        rows = super().get_queryset(request)
        return rows if request.user.is_superuser else rows.filter(owner=request.user)

    def get_exclude(self, request, obj=None):
        excluded = list(super().get_exclude(request, obj) or [])
        return excluded if request.user.is_superuser else [*excluded, "owner"]

    def save_model(self, request, obj, form, change):
        if not change and not request.user.is_superuser:
            obj.owner = request.user
        super().save_model(request, obj, form, change)
