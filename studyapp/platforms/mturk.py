"""MTurk's requester API through boto3: the calls a study's review needs, sent to MTurk's
sandbox unless the researcher asks for the real marketplace.

    approve    ApproveAssignment      {"AssignmentId", "RequesterFeedback"}
    reject     RejectAssignment       {"AssignmentId", "RequesterFeedback"} (the worker reads it)
    bonuses    SendBonus              {"WorkerId", "AssignmentId", "BonusAmount", "Reason", "UniqueRequestToken"}
    read back  ListAssignmentsForHIT  {"HITId", "MaxResults"} (pages followed)

MTurk has no request to return a submission: a worker who submitted is approved or
rejected. SendBonus's UniqueRequestToken makes MTurk itself refuse a bonus sent twice.

botocore takes any 2xx answer for success, whatever it holds (an HTML page, broken or
cut JSON): here only a JSON object in MTurk's content type confirms a call
(``_answer_is_mturks``). A 4xx is MTurk's refusal; a server error, a redirect or an answer
cut short raises ``UnconfirmedAnswer`` (MTurk may or may not have done it), and a listing
is read to ``MAX_PAGES`` pages at most.
"""

from __future__ import annotations

import hashlib
import json
from decimal import Decimal

import boto3
from botocore.config import Config
from botocore.exceptions import BotoCoreError, ClientError, HTTPClientError
from botocore.exceptions import ConnectionError as NotReached
from botocore import xform_name
from django.conf import settings

from studyapp.platforms.calls import Call, Payee, PlatformError, UnconfirmedAnswer
from studyapp.platforms.json_exchange import shown
from studyapp.platforms.rules import APPROVE, REJECT

NAME = "MTurk"
REGION = "us-east-1"  # MTurk's only region
PAGE_SIZE = 100
MAX_PAGES = 1000
APPROVAL_FEEDBACK = "Thank you for taking part."


def rejection_feedback(failed_checks: int) -> str:
    checks = "an attention check" if failed_checks == 1 else f"{failed_checks} attention checks"
    return (f"Rejected because {checks} in the task were not answered as the page asked: each told you which "
            f"answer to give, whatever you thought of the video.")


class MTurkAPI:
    name = NAME

    def __init__(self, access_key_id: str, secret_access_key: str, sandbox: bool = True) -> None:
        self.sandbox = sandbox
        self.address = settings.MTURK_SANDBOX_API_URL if sandbox else settings.MTURK_API_URL
        self._client = boto3.client(
            "mturk", region_name=REGION, endpoint_url=self.address, aws_access_key_id=access_key_id,
            aws_secret_access_key=secret_access_key, config=Config(retries={"max_attempts": 3, "mode": "standard"}))
        self._client.meta.events.register("before-parse.mturk", _answer_is_mturks)

    # What will be sent (the dry run)

    def decision(self, payee: Payee, action: str, failed_checks: int, why: str) -> Call | None:
        if action == APPROVE:
            return Call(f"approve:{payee.session}", action, payee.platform_id, "ApproveAssignment",
                        {"AssignmentId": payee.session, "RequesterFeedback": APPROVAL_FEEDBACK})
        if action == REJECT:
            return Call(f"reject:{payee.session}", action, payee.platform_id, "RejectAssignment",
                        {"AssignmentId": payee.session, "RequesterFeedback": rejection_feedback(failed_checks)})
        return None  # MTurk cannot ask for a return

    def bonuses(self, amounts: list[tuple[Payee, Decimal]], reason: str) -> list[Call]:
        calls = []
        for payee, amount in amounts:
            key = f"bonus:{payee.session}:{amount}:{hashlib.sha256(reason.encode()).hexdigest()[:12]}"
            token = hashlib.sha256(key.encode()).hexdigest()  # 64 characters: MTurk refuses a second bonus with it
            calls.append(Call(key, "bonus", payee.platform_id, "SendBonus", {
                "WorkerId": payee.platform_id, "AssignmentId": payee.session, "BonusAmount": str(amount),
                "Reason": reason, "UniqueRequestToken": token}))
        return calls

    def reads(self, groups: list[str]) -> list[Call]:
        return [Call(f"read:{hit}", "read", "", "ListAssignmentsForHIT", {"HITId": hit, "MaxResults": PAGE_SIZE})
                for hit in sorted(groups)]

    # Sending

    def send(self, call: Call, answers: dict[str, dict]) -> dict:
        operation = getattr(self._client, xform_name(call.operation))
        try:
            if call.operation == "ListAssignmentsForHIT":
                return {"Assignments": self._listed(call)}
            answer = operation(**call.body)
        except ClientError as error:
            details = error.response.get("Error", {})
            words = shown(str(details.get("Message") or details.get("Code") or error))
            status = error.response.get("ResponseMetadata", {}).get("HTTPStatusCode")
            if isinstance(status, int) and 400 <= status < 500:
                raise PlatformError(f"MTurk refused: {words}", status) from None
            raise UnconfirmedAnswer(f"MTurk answered {status}, which confirms nothing: {words}", status) from None
        except NotReached as error:
            raise PlatformError(f"MTurk could not be reached at {self.address}: {error}") from None
        except HTTPClientError as error:  # sent; the answer is missing or cut short
            raise UnconfirmedAnswer(f"MTurk gave no whole answer ({shown(str(error))}); it may have done it or "
                                    f"not") from None
        except BotoCoreError as error:
            raise PlatformError(f"the request to MTurk failed: {shown(str(error))}") from None
        answer.pop("ResponseMetadata", None)
        return _plain(answer)

    def _listed(self, call: Call) -> list:
        assignments = []
        for number, page in enumerate(self._client.get_paginator(xform_name(call.operation)).paginate(**call.body),
                                      start=1):
            if number > MAX_PAGES:
                raise UnconfirmedAnswer(f"MTurk's listing goes on past {MAX_PAGES} pages: the assignments were not "
                                        f"read")
            assignments += page.get("Assignments", [])
        return assignments

    def statuses(self, answer: dict) -> dict[str, str]:
        """Each assignment's status, by assignment id; PlatformError for a listing that names none."""
        listed = answer.get("Assignments")
        if not isinstance(listed, list) or not all(
                isinstance(a, dict) and isinstance(a.get("AssignmentId"), str) and isinstance(
                    a.get("AssignmentStatus", ""), str) for a in listed):
            raise UnconfirmedAnswer("MTurk's listing has an assignment without an id or a status")
        return {a["AssignmentId"]: a.get("AssignmentStatus", "") for a in listed}


def _answer_is_mturks(response_dict: dict, **_) -> None:
    """botocore's hook before it reads an answer: a 2xx that is not a JSON object in MTurk's
    content type confirms nothing (botocore would take it for success)."""
    if not 200 <= response_dict["status_code"] < 300:
        return
    kind = response_dict["headers"].get("content-type", "")
    try:
        answer = json.loads(response_dict["body"] or b"null")
    except (ValueError, RecursionError):
        answer = None
    if not kind.startswith("application/x-amz-json") or not isinstance(answer, dict):
        raise UnconfirmedAnswer(f"MTurk answered {response_dict['status_code']} with {shown(kind) or 'no type'}, "
                                f"not its JSON, which confirms nothing: "
                                f"{shown(response_dict['body'].decode('utf-8', errors='replace'))}",
                                response_dict["status_code"])


def _plain(value: object) -> object:
    """An answer with its dates as text, so that it can be kept as JSON."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_plain(item) for item in value]
    return value if isinstance(value, str | int | float | bool | type(None)) else str(value)


__all__ = ["MTurkAPI", "NAME", "rejection_feedback"]
