"""A study's requests to its crowd platform: planned from the participant list (the dry
run), sent once each, and logged.

``decision_calls`` are the suggested approvals, rejections and return requests of the
participant list (``platforms.rules``), ``bonus_calls`` the bonuses of a list of
"<platform id>,<amount>" lines, and ``read_back`` reads the platform's submissions of the
study to set beside the list. ``apply`` sends each planned call whose key was never done,
in order, and keeps every attempt (``PlatformAction``) and logs it: a retry after a
failure sends only what is still undone, and a call refused by the platform holds back
only the calls that need its answer. A call whose answer does not confirm it
(``UnconfirmedAnswer``: a server error, a timeout, an answer that is not the API's) is
kept as failed and reported as not confirmed: it stays undone, and the researcher is
asked to look on the platform's pages before sending it again.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation

from django.contrib.auth.models import AbstractBaseUser
from django.db import IntegrityError
from django.utils import timezone

from studyapp.models import Participant, PlatformAction, Study
from studyapp.platforms.links import SESSION_PARAMETERS
from studyapp.platforms.calls import Call, Payee, PlatformError, UnconfirmedAnswer, is_platform_id
from studyapp.platforms.mturk import MTurkAPI
from studyapp.platforms.prolific import ProlificAPI
from studyapp.platforms.rules import APPROVE, REJECT, REQUEST_RETURN, Standing
from studyapp.researchers.crowd.participant_list import participant_rows

logger = logging.getLogger("studyapp.platforms")

GROUP_PARAMETERS = {Study.Platform.PROLIFIC: "STUDY_ID", Study.Platform.MTURK: "hitId"}
# What a participant asked to return their submission reads (Prolific words a message around it).
RETURN_REASONS = {Standing.STOPPED: "The study stopped after answers that did not follow the instructions shown on "
                                    "the page, so it was not finished.",
                  Standing.SCREENED_OUT: "The answers to the screening questions did not match what this study "
                                         "looks for."}
SENT, ALREADY_DONE, REFUSED, UNCONFIRMED, HELD_BACK = "sent", "already done", "refused", "not confirmed", "not sent"
LARGEST_BONUS = Decimal("100")

PlatformAPI = ProlificAPI | MTurkAPI


class BonusListError(ValueError):
    """A bonus list line that cannot be paid; the message names the line."""


class PlanChanged(Exception):
    """The calls asked for are no longer those the dry run listed."""


@dataclass(frozen=True)
class Planned:
    call: Call
    done_before: bool  # its key was done: applying sends nothing


@dataclass(frozen=True)
class Result:
    call: Call
    outcome: str  # SENT, ALREADY_DONE, REFUSED, UNCONFIRMED, HELD_BACK
    detail: str


@dataclass(frozen=True)
class ReadRow:
    platform_id: str
    session: str
    status: str  # ours (the participant list's)
    suggested_action: str
    on_platform: str  # the platform's status of the submission ("" if it does not list it)


def platform_api(study: Study, credentials: dict) -> PlatformAPI:
    """The API of ``study``'s platform, with the researcher's credentials."""
    if study.platform == Study.Platform.PROLIFIC:
        return ProlificAPI(credentials["token"])
    if study.platform == Study.Platform.MTURK:
        return MTurkAPI(credentials["access_key_id"], credentials["secret_access_key"], credentials["sandbox"])
    raise ValueError(f"a {study.get_platform_display()} study has no platform to send requests to")


def _payee(study: Study, participant: Participant) -> Payee:
    data = participant.platform_data
    return Payee(participant.platform_id, data.get(SESSION_PARAMETERS[study.platform], ""),
                 data.get(GROUP_PARAMETERS[study.platform], ""))


def decision_calls(study: Study, api: PlatformAPI) -> list[Call]:
    """The participant list's suggested approvals, rejections and return requests, for
    those who are done and whose submission the platform named."""
    participants = {p.platform_id: p for p in study.participants.all()}
    calls = []
    for row in participant_rows(study):
        if row.suggested_action not in (APPROVE, REJECT, REQUEST_RETURN) or not is_platform_id(row.session):
            continue
        call = api.decision(_payee(study, participants[row.platform_id]), row.suggested_action, row.failed_checks,
                            RETURN_REASONS.get(Standing(row.status), ""))
        if call is not None:
            calls.append(call)
    return calls


def without_submission(study: Study) -> list[str]:
    """Platform ids with a suggested decision that no request can carry: their entry link
    brought no submission id, or one no platform gives (it would go into the request's
    path: "../", a query): decide them on the platform's own pages."""
    return [row.platform_id for row in participant_rows(study)
            if row.suggested_action in (APPROVE, REJECT, REQUEST_RETURN) and not is_platform_id(row.session)]


def bonus_calls(study: Study, api: PlatformAPI, text: str, reason: str) -> list[Call]:
    """The calls that pay the bonuses of ``text``: one "<platform id>,<amount>" a line
    (the amount in the study's currency, e.g. 1.50); BonusListError names a bad line."""
    participants = {p.platform_id: p for p in study.participants.all()}
    amounts: list[tuple[Payee, Decimal]] = []
    seen: set[str] = set()
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        platform_id, _, amount_text = (part.strip() for part in line.rpartition(","))
        if not platform_id:
            raise BonusListError(f"line {number}: expected '<platform id>,<amount>', got {line.strip()[:60]!r}")
        participant = participants.get(platform_id)
        if participant is None:
            raise BonusListError(f"line {number}: {platform_id[:60]!r} is not a participant of this study")
        if platform_id in seen:
            raise BonusListError(f"line {number}: {platform_id[:60]!r} is listed twice")
        try:
            amount = Decimal(amount_text)
        except InvalidOperation:
            raise BonusListError(f"line {number}: the amount {amount_text[:20]!r} is not a number") from None
        if not amount.is_finite() or amount <= 0 or amount > LARGEST_BONUS or amount != amount.quantize(Decimal("0.01")):
            raise BonusListError(f"line {number}: the amount must be above 0 and at most {LARGEST_BONUS}, in "
                                 f"cents at most (e.g. 1.50), not {amount_text[:20]!r}")
        payee = _payee(study, participant)
        if not is_platform_id(payee.session) or not is_platform_id(payee.group):
            raise BonusListError(f"line {number}: {platform_id[:60]!r} came without a submission id and study id "
                                 f"as the platform gives them")
        seen.add(platform_id)
        amounts.append((payee, amount.quantize(Decimal("0.01"))))
    if not amounts:
        raise BonusListError("the bonus list is empty: give one '<platform id>,<amount>' a line")
    if study.platform == Study.Platform.MTURK and not reason.strip():
        raise BonusListError("MTurk shows each bonus with its reason: give one")
    return api.bonuses(amounts, reason.strip())


def planned(study: Study, calls: list[Call]) -> list[Planned]:
    """``calls`` as the dry run lists them: each with whether it was done before."""
    done = _done_keys(study, [call.key for call in calls])
    return [Planned(call, call.key in done) for call in calls]


def chosen(calls: list[Call], digests: list[str]) -> list[Call]:
    """The calls of ``digests``, in plan order; PlanChanged if one is no longer planned as shown."""
    wanted = set(digests)
    if missing := wanted - {call.digest for call in calls}:
        raise PlanChanged(f"{len(missing)} of the requests differ from the dry run (the participant list changed "
                          f"since): review the dry run again")
    return [call for call in calls if call.digest in wanted]


def apply(study: Study, api: PlatformAPI, calls: list[Call], researcher: AbstractBaseUser) -> list[Result]:
    """Send each call whose key was never done, in order; keep and log every attempt."""
    done = _done_keys(study, [call.key for call in calls])
    answers = {action.key: action.response for action in PlatformAction.objects.filter(
        study=study, outcome=PlatformAction.Outcome.DONE, key__in=[call.after for call in calls if call.after])}
    participants = {p.platform_id: p for p in study.participants.all()}
    results = []
    for call in calls:
        if call.key in done:
            results.append(Result(call, ALREADY_DONE, "sent before: not sent again"))
            continue
        if call.after and call.after not in answers:
            results.append(Result(call, HELD_BACK, f"it needs the answer to {call.after}, which has none"))
            continue
        record = {"study": study, "participant": participants.get(call.platform_id), "researcher": researcher,
                  "platform": study.platform, "key": call.key, "action": call.action,
                  "request": {"operation": call.operation, "address": api.address, "body": call.body}}
        try:
            answer = api.send(call, answers)
        except PlatformError as error:
            outcome, detail = _failure(error, api.name)
            PlatformAction.objects.create(**record, outcome=PlatformAction.Outcome.FAILED, response={
                "error": detail if outcome == REFUSED else f"{outcome}: {detail}", "status": error.status})
            logger.warning("study %s: %s %s %s %s by %s: %s", study.pk, researcher, call.action, call.key,
                           outcome, api.name, error)
            results.append(Result(call, outcome, detail))
            continue
        try:
            PlatformAction.objects.create(**record, outcome=PlatformAction.Outcome.DONE, response=answer)
        except IntegrityError:  # another request of the researcher's sent it meanwhile
            results.append(Result(call, ALREADY_DONE, "sent meanwhile by another request"))
            continue
        answers[call.key] = answer
        done.add(call.key)
        logger.info("study %s: %s %s %s sent to %s", study.pk, researcher, call.action, call.key, api.name)
        results.append(Result(call, SENT, "done"))
    return results


def _failure(error: PlatformError, platform: str) -> tuple[str, str]:
    """What a call that was not done reports: refused, or not confirmed (it may have been
    done: it stays undone, so that a later apply sends it again once the researcher has looked)."""
    if isinstance(error, UnconfirmedAnswer):
        return UNCONFIRMED, (f"{error}. It is not recorded as done: look on {platform}'s own pages whether it was "
                             f"done before sending it again")
    return REFUSED, str(error)


def read_back(study: Study, api: PlatformAPI, researcher: AbstractBaseUser) -> list[ReadRow]:
    """The platform's status of every participant's submission beside the participant
    list's; a refused read raises PlatformError."""
    reads = api.reads(sorted(group for group in {_payee(study, p).group for p in study.participants.all()}
                             if is_platform_id(group)))  # it goes into the request's path
    statuses: dict[str, str] = {}
    for call in reads:
        statuses |= api.statuses(api.send(call, {}))
        logger.info("study %s: %s read %s from %s", study.pk, researcher, call.key, api.name)
    PlatformAction.objects.create(
        study=study, researcher=researcher, platform=study.platform, key=f"read:{timezone.now().isoformat()}",
        action="read", request={"operation": "; ".join(call.operation for call in reads), "address": api.address,
                                "bodies": [call.body for call in reads]},
        outcome=PlatformAction.Outcome.DONE, response={"status": f"{len(statuses)} submissions", "statuses": statuses})
    return [ReadRow(row.platform_id, row.session, row.status, row.suggested_action, statuses.get(row.session, ""))
            for row in participant_rows(study)]


def _done_keys(study: Study, keys: list[str]) -> set[str]:
    return set(PlatformAction.objects.filter(study=study, outcome=PlatformAction.Outcome.DONE, key__in=keys)
               .values_list("key", flat=True))


__all__ = ["ALREADY_DONE", "BonusListError", "HELD_BACK", "PlanChanged", "Planned", "REFUSED", "ReadRow", "Result",
           "SENT", "UNCONFIRMED", "apply", "bonus_calls", "chosen", "decision_calls", "planned", "platform_api",
           "read_back", "without_submission"]
