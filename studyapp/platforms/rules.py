"""What a crowd platform's published rules let a researcher do with a participant's
submission: the suggested action of the participant list, with its reason in words.

Paying a participant and analysing their ratings are separate questions. A rating that
judges the motion badly (a BAD clip rated natural, a NAT clip rated unnatural) excludes
the participant from the analysis (``Participant.excluded``) but is a judgement of
quality, which no platform here accepts as grounds for refusing payment: they are
approved. Only failed *instructed* checks (pages that say which answer to give,
the designs' instructed checks) may lead to a rejection, and only as many as the rules ask:

- Prolific's attention-check policy (researcher-help.prolific.com, "Using attention
  checks as a measure of data quality"; "Valid rejection reasons"): rejection for failed
  instructional manipulation checks, one failed check for a study shorter than 5 minutes,
  at least two for a study of 5 minutes or more. The study's length is the median time
  of the participants who finished it (Prolific's own measure is its average completion
  time); until someone has finished, two are asked for. Participants who fail fewer may
  be asked to return their submission, never rejected; those screened out get the
  study's screen-out code, which Prolific pays at the fixed screen-out rate.
- MTurk (AWS, "Approving and rejecting work"): reject only work that shows no effort,
  never a mistake. One failed instructed check can be a mistake, so two are asked for.
  MTurk has no return request: a worker who submits is approved or rejected.
- A plain link has no platform rules; the suggestion follows MTurk's, the stricter.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from enum import StrEnum

from studyapp.models import Study

APPROVE, REJECT, REQUEST_RETURN, NOTHING = "approve", "reject", "request return", ""
PROLIFIC_SHORT_STUDY_MINUTES = 5.0  # shorter studies may reject after one failed check
CHECKS_FOR_REJECTION = 2  # Prolific for studies of 5 minutes or more; MTurk and plain links always


class Standing(StrEnum):
    """How far a participant got."""
    IN_PROGRESS = "in progress"
    IDLE = "idle"  # away longer than the reservation
    SCREENED_OUT = "screened out"
    STOPPED = "stopped by checks"  # failed the study's stop_after_failed_checks instructed checks
    FINISHED = "finished"


@dataclass(frozen=True)
class Submission:
    """What the rules read of one participant."""
    standing: Standing
    failed_checks: int  # instructed checks answered otherwise than asked
    exclusion_reason: str  # why their ratings are left out of the analysis ("": kept)


@dataclass(frozen=True)
class Suggestion:
    action: str  # APPROVE, REJECT, REQUEST_RETURN or NOTHING
    reason: str  # in words, for the researcher


def study_minutes(finished_minutes: list[float]) -> float | None:
    """The study's length for Prolific's 5-minute rule: the median minutes of those who
    finished every page (None before anyone has)."""
    return statistics.median(finished_minutes) if finished_minutes else None


def checks_for_rejection(study: Study, minutes: float | None) -> int:
    """How many failed instructed checks the platform's rules ask for before a rejection."""
    if study.platform == Study.Platform.PROLIFIC and minutes is not None and minutes < PROLIFIC_SHORT_STUDY_MINUTES:
        return 1
    return CHECKS_FOR_REJECTION


def suggest(study: Study, submission: Submission, minutes: float | None) -> Suggestion:
    """The action the study's platform's rules suggest for ``submission``, and why."""
    if submission.standing in (Standing.IN_PROGRESS, Standing.IDLE):
        return Suggestion(NOTHING, "not finished yet")
    needed = checks_for_rejection(study, minutes)
    failed = submission.failed_checks
    rules = _rules(study, minutes)
    if failed >= needed:
        return Suggestion(REJECT, f"{_failed(failed)}; {rules} allows a rejection after {needed}")
    if submission.standing == Standing.SCREENED_OUT:
        return _screened_out(study)
    below = f"{rules} allows a rejection only after {needed}"
    if submission.standing == Standing.STOPPED:
        if study.platform == Study.Platform.PROLIFIC:
            return Suggestion(REQUEST_RETURN, f"{_failed(failed)} and was stopped; {below}: ask for a return, and "
                                              f"approve if they decline")
        return Suggestion(APPROVE, f"{_failed(failed)} and was stopped; {below}")
    reasons = ["finished"]
    if failed:
        reasons.append(f"{_failed(failed)}, and {below}")
    if submission.exclusion_reason:
        reasons.append(f"excluded from the analysis ({submission.exclusion_reason}): a judgement of the ratings, "
                       f"no ground for refusing payment")
    return Suggestion(APPROVE, "; ".join(reasons))


def _screened_out(study: Study) -> Suggestion:
    if study.platform == Study.Platform.PROLIFIC:
        if study.screen_out_code:
            return Suggestion(NOTHING, "screened out: their screen-out code has Prolific pay the fixed screen-out "
                                       "reward")
        return Suggestion(REQUEST_RETURN, "screened out and asked to return the study (it has no screen-out code)")
    return Suggestion(APPROVE, "screened out by a screening question: they did what was asked of them")


def _failed(count: int) -> str:
    return f"failed {count} instructed attention check{'s' if count != 1 else ''}"


def _rules(study: Study, minutes: float | None) -> str:
    if study.platform == Study.Platform.PROLIFIC:
        length = "no one has finished yet" if minutes is None else f"a study of {minutes:.1f} min"
        return f"Prolific's attention-check policy ({length})"
    if study.platform == Study.Platform.MTURK:
        return "MTurk's guidance (one slip is no ground)"
    return "the rule suggested here"


__all__ = ["APPROVE", "NOTHING", "REJECT", "REQUEST_RETURN", "Standing", "Submission", "Suggestion",
           "checks_for_rejection", "study_minutes", "suggest"]
