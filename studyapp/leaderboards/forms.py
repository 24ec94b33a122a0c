"""The board pages' forms: a board's settings, a round added, a round in or out of the fit,
and the admin's rounds (held to the same rules: a rated round stays on its board)."""

from __future__ import annotations

from django import forms
from django.core.exceptions import ValidationError

from studyapp.leaderboards.models import Leaderboard, Round
from studyapp.models import Rating, Study


def is_rated(round_: Round) -> bool:
    """Whether the round's study has a rating: its votes may have been shown, so the round
    stays on its board (it can leave the fit, with a reason, but not the board)."""
    return Rating.objects.filter(assignment__participant__study_id=round_.study_id).exists()


class LeaderboardForm(forms.ModelForm):
    class Meta:
        model = Leaderboard
        fields = ["title", "description", "anchor", "public"]
        widgets = {"description": forms.Textarea(attrs={"rows": 3})}


class RoundForm(forms.Form):
    """A pairwise study of the researcher's that is no board's round yet."""

    study = forms.ModelChoiceField(queryset=Study.objects.none(), label="Pairwise study")

    def __init__(self, *args, owner, **kwargs):
        super().__init__(*args, **kwargs)
        self.fields["study"].queryset = (Study.objects.filter(owner=owner, design="pairwise", board_round__isnull=True)
                                         .order_by("created", "pk"))


class RoundFitForm(forms.ModelForm):
    class Meta:
        model = Round
        fields = ["in_fit", "left_out_because"]
        labels = {"in_fit": "In the fit", "left_out_because": "Why it is left out"}

    def clean(self):
        cleaned = super().clean()
        if not cleaned.get("in_fit") and not (cleaned.get("left_out_because") or "").strip():
            self.add_error("left_out_because", "say why the round is left out: the board states it")
        return cleaned


class AdminRoundForm(RoundFitForm):
    """A round in the admin: the board page's rules, and a rated round's study kept."""

    class Meta(RoundFitForm.Meta):
        fields = ["study", "in_fit", "left_out_because"]

    def clean_study(self):  # before the instance takes the new study (Django's _post_clean)
        study = self.cleaned_data["study"]
        if self.instance.pk and study.pk != self.instance.study_id and is_rated(self.instance):
            raise ValidationError("this round's study has ratings, so it stays the round's study")
        return study


class AdminRoundFormSet(forms.BaseInlineFormSet):
    """The admin's rounds of a board: a rated round cannot be deleted (as on the board page)."""

    def clean(self):
        super().clean()
        for form in self.deleted_forms:
            if form.instance.pk and is_rated(form.instance):
                raise ValidationError(f"{form.instance.study.title} has ratings, so it stays on the board: leave it "
                                      "out of the fit instead, saying why.")
