"""Forms of the platform page: the researcher's credentials and a list of bonuses."""

from __future__ import annotations

from django import forms

from studyapp.platforms.credentials import validate_secret_text


class ProlificCredentialsForm(forms.Form):
    token = forms.CharField(
        label="Prolific API token", max_length=500, strip=True, widget=forms.PasswordInput(render_value=False),
        validators=[validate_secret_text], help_text="Prolific: your account › API tokens › Create API token")

    def secret(self) -> dict:
        return {"token": self.cleaned_data["token"]}


class MTurkCredentialsForm(forms.Form):
    access_key_id = forms.CharField(label="AWS access key id", max_length=128, strip=True,
                                    validators=[validate_secret_text])
    secret_access_key = forms.CharField(label="AWS secret access key", max_length=128, strip=True,
                                        widget=forms.PasswordInput(render_value=False),
                                        validators=[validate_secret_text])
    live = forms.BooleanField(label="Send to the real MTurk marketplace", required=False,
                              help_text="unticked: MTurk's requester sandbox, where nothing is paid")

    def secret(self) -> dict:
        data = self.cleaned_data
        return {"access_key_id": data["access_key_id"], "secret_access_key": data["secret_access_key"],
                "sandbox": not data["live"]}


class BonusForm(forms.Form):
    bonuses = forms.CharField(
        label="Bonuses", widget=forms.Textarea(attrs={"rows": 5, "placeholder": "5f3a…,1.50"}),
        help_text="one a line: the participant's platform id, a comma, the amount in the study's currency (1.50)")
    reason = forms.CharField(label="Reason", max_length=300, required=False,
                             help_text="MTurk shows it with the bonus (needed there); Prolific has no such field")


__all__ = ["BonusForm", "MTurkCredentialsForm", "ProlificCredentialsForm"]
