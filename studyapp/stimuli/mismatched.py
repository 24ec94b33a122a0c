"""An appropriateness study's mismatched clips: which control each shown control is paired
with, and the clips that pairing needs.

An appropriateness page shows one system's clip made for the page's control and the same
system's clip made for the control's *partner*, both drawn over the shown control's path
(``clips.render_stimulus``). The partners come from ``generation.mismatch``'s rule over
all of the study's controls, seeded by the study: held-out controls pair with held-out
controls (NAT's mismatched clip is another take), and every system gets the same
partner for a control, so their scores compare like with like. NAT's attention checks
pair a held-out control with the obviously wrong take the rule's attention partner gives.

A mismatched clip is a ``Stimulus`` whose ``control`` is the partner and whose
``shown_control`` is the control the page shows: the system's motion for the partner
(the clip of the partner's own page, cut to the shown control's length), not sampled
again. The pairs are worked out anew from the controls (``study_pairings``), so adding
or renaming a control before the study starts gives every page the rule's current
partner; the work is cached per set of controls, since enrolment asks for it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

from generation.control import control_from_dict
from generation.mismatch import Mismatch, choose_attention_checks, choose_mismatches
from studyapp.models import ControlSignal, Study, System
from studyapp.stimuli.sources import source_of


@dataclass(frozen=True)
class ControlPairing:
    """A shown control with its partner and NAT's attention-check partner (either may be None)."""

    shown: ControlSignal
    partner: ControlSignal | None
    mismatch: Mismatch  # how the partner was chosen, or why there is none, with the rule's measures
    attention: ControlSignal | None = None
    attention_check: Mismatch | None = None  # None where NAT cannot show the control

    @property
    def checked_with(self) -> ControlSignal | None:
        """The take NAT's attention check of this control shows beside it: the attention
        partner, unless that is the partner already (the check would be NAT's rated page
        of the control again, so the control makes no check)."""
        return self.attention if self.attention != self.partner else None


def study_pairings(study: Study) -> list[ControlPairing]:
    """Every control of the study with its partners, in the controls' order."""
    controls = list(study.controls.all())
    if not controls:
        return []
    by_name = {c.name: c for c in controls}
    described = json.dumps([[c.name, c.control, bool(c.source_clip)] for c in controls], sort_keys=True)
    with_nat = study.systems.filter(role=System.Role.NATURAL).exists()
    mismatches, attention = _chosen(study.pk, described, with_nat)
    return [ControlPairing(control, by_name.get(m.partner.name) if m.partner else None, m,
                           *((by_name.get(a.partner.name) if a.partner else None, a) if a else (None, None)))
            for control, m, a in zip(controls, mismatches, attention)]


@lru_cache(maxsize=32)
def _chosen(seed: int, described: str, with_nat: bool) -> tuple[list[Mismatch], list[Mismatch | None]]:
    """The rule's partners of the controls ``described`` (name, control, cut from a take), by ``seed``."""
    entries = json.loads(described)
    signals = [control_from_dict({**control, "name": name}) for name, control, _ in entries]
    takes = {name for name, _, take in entries if take}
    mismatches = choose_mismatches(signals, seed, takes)
    checks = choose_attention_checks(signals, seed, takes) if with_nat and takes else [None] * len(signals)
    return mismatches, [check if name in takes else None for (name, _, _), check in zip(entries, checks)]


def mismatched_clips(study: Study) -> list[tuple[System, ControlSignal, ControlSignal]]:
    """(system, the control the clip is made for, the control shown) of every mismatched
    clip the study's pages need: each compared system's clip of each shown control's
    partner, where its source has motion for both, and NAT's clip of each take its checks show."""
    pairings = study_pairings(study)
    controls = [pairing.shown for pairing in pairings]
    wanted = []
    for system in study.systems.exclude(role=System.Role.BAD):
        has = {c.pk for c in source_of(system).controls(system, controls)}
        pairs = [(p.partner, p.shown) for p in pairings if p.partner]
        if system.role == System.Role.NATURAL:
            pairs += [(p.checked_with, p.shown) for p in pairings if p.checked_with]
        wanted += [(system, partner, shown) for partner, shown in pairs if partner.pk in has and shown.pk in has]
    return wanted


__all__ = ["ControlPairing", "mismatched_clips", "study_pairings"]
