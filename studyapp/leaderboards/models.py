"""A leaderboard that spans studies, and its rounds.

A ``Leaderboard`` belongs to a researcher; each ``Round`` is one of their pairwise studies
added to it. A study is a round of at most one board (its adaptive pairing then plans
against that board). Systems across rounds are one system when their names in the ratings
table are equal (``System.export_name``: the name, NAT and BAD for those roles). A round's
study's ratings are only read. A round left out of the fit (``in_fit`` off) stays on the
board, listed as left out; only a round whose study has no rating yet can be removed. The
public page is off until the researcher turns it on; its address carries ``public_key``,
which says nothing about the board.
"""

from __future__ import annotations

import secrets

from django.conf import settings
from django.db import models


def new_public_key() -> str:
    """The unguessable part of a board's public address."""
    return secrets.token_urlsafe(18)


class Leaderboard(models.Model):
    """A researcher's leaderboard, fitted on the votes of its rounds."""

    owner = models.ForeignKey(settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="leaderboards")
    title = models.CharField(max_length=200)
    description = models.TextField(blank=True, help_text="shown above the board, on the public page too")
    anchor = models.CharField(max_length=100, default="NAT",
                              help_text="the system at Elo 1000 (where it was compared; else the systems' mean)")
    public = models.BooleanField(default=False, help_text="show the board read-only at its public address")
    public_key = models.CharField(max_length=32, unique=True, default=new_public_key, editable=False)
    created = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["-created", "pk"]

    def __str__(self) -> str:
        return self.title


class Round(models.Model):
    """One pairwise study's votes on a board; ``in_fit`` off leaves them out of the fit."""

    leaderboard = models.ForeignKey(Leaderboard, on_delete=models.CASCADE, related_name="rounds")
    study = models.OneToOneField("studyapp.Study", on_delete=models.CASCADE, related_name="board_round")
    in_fit = models.BooleanField(default=True)
    left_out_because = models.CharField(max_length=300, blank=True,
                                        help_text="why the round is left out of the fit (shown on the board)")
    added = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["added", "pk"]

    def __str__(self) -> str:
        return f"{self.leaderboard}: {self.study}"
