"""Whether a study may open to participants, and if not, why.

A study opens only with clips to rate and with what its crowd platform needs to pay the
participants who finish: Prolific a completion code or URL, and a screen-out code where
screening questions can turn participants away (Prolific allows in-study screening only
with its fixed screen-out payment); MTurk its frame over HTTPS (the participant's link
brings the submit target, which ``participants.views`` checks on entry). The monitor's
open button lists the reasons; the open view refuses on them. Warnings (attention checks
without the system that makes them, what could tell the systems apart besides their
motion: ``unblinding``) do not stop it, once the researcher has seen them: the monitor
shows them beside the button. A rig the display figure cannot be placed on stops it.
"""

from __future__ import annotations

from django.conf import settings

from studyapp.designs.registry import design_of
from studyapp.models import Question, Stimulus, Study, System
from studyapp.researchers.setup.unblinding import unblinding


def open_problems(study: Study) -> list[str]:
    """What stops ``study`` from opening, in words for the researcher (empty: it may open)."""
    problems = []
    rated = study.stimuli.filter(status=Stimulus.Status.DONE).exclude(system__role=System.Role.BAD)
    if not rated.exists():
        problems.append("no finished clip to rate: generate the stimuli first")
    if study.platform == Study.Platform.PROLIFIC and not (study.completion_code or study.redirect_url):
        problems.append("Prolific pays only participants who bring back its completion code: "
                        "set the completion code (or the completion URL) in the settings")
    screens = study.questions.filter(part=Question.Part.BEFORE).exclude(accepted="").exists()
    if study.platform == Study.Platform.PROLIFIC and screens and not study.screen_out_code:
        problems.append("Prolific lets a study screen participants out only with a screen-out completion code, "
                        "which it pays at a fixed amount: set the screen-out code in the settings (and add it on "
                        "Prolific as a 'screened out' code)")
    if study.platform == Study.Platform.MTURK and not settings.HTTPS:
        problems.append("MTurk shows the study in a frame of its HTTPS site, which needs this server "
                        "behind HTTPS with HTTPS=1 set")
    return problems + unblinding(study)[0]


def open_warnings(study: Study) -> list[str]:
    """What the study may open with but is probably a mistake, in words for the researcher:
    attention checks asked for without the system that makes them, or without clips of it
    that make one."""
    warnings = []
    finished = study.stimuli.filter(status=Stimulus.Status.DONE)
    design = design_of(study)
    made_of = design.attention_check_role
    system = "BAD" if made_of == System.Role.BAD else "NAT"
    if study.bad_checks and not design.makes_attention_checks(study, finished):
        if not finished.filter(system__role=made_of).exists():
            why, remedy = (f"the study has no {system} system with a finished clip",
                           f"add a {system} system on the systems page and generate its clips")
        else:
            why, remedy = (f"no finished {system} clip makes one (the stimuli page says why for each control)",
                           "add held-out controls")
        warnings.append(f"the settings ask for {study.bad_checks} BAD check(s) per participant, but {why}, so no "
                        f"participant gets one and none can be excluded for it: {remedy}, or set BAD checks to 0")
    if "natural_checks" in design.settings and study.natural_checks \
            and not finished.filter(system__role=System.Role.NATURAL).exists():
        warnings.append(f"the settings ask for {study.natural_checks} NAT check(s) per participant, but the study "
                        "has no NAT system with a finished clip: add NAT on the systems page, or set NAT checks to 0")
    return warnings + unblinding(study)[1]


__all__ = ["open_problems", "open_warnings"]
