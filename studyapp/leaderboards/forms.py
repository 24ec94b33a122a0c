"""The board pages' forms: a board's settings, a round added, a round in or out of the fit."""

from __future__ import annotations

from django import forms

from studyapp.leaderboards.models import Leaderboard, Round
from studyapp.models import Study


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
