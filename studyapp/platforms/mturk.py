"""MTurk's requester API through boto3: the calls a study's review needs, sent to MTurk's
sandbox unless the researcher asks for the real marketplace.

    approve    ApproveAssignment      {"AssignmentId", "RequesterFeedback"}
    reject     RejectAssignment       {"AssignmentId", "RequesterFeedback"} (the worker reads it)
    bonuses    SendBonus              {"WorkerId", "AssignmentId", "BonusAmount", "Reason", "UniqueRequestToken"}
    read back  ListAssignmentsForHIT  {"HITId", "MaxResults"} (pages followed)

MTurk has no request to return a submission: a worker who submitted is approved or
rejected. SendBonus's UniqueRequestToken makes MTurk itself refuse a bonus sent twice.
"""

from __future__ import annotations

import hashlib
from decimal import Decimal

import boto3
from botocore.config import Config
from botocore.exceptions import BotoCoreError, ClientError
from botocore import xform_name
from django.conf import settings

from studyapp.platforms.calls import Call, Payee, PlatformError, UnconfirmedAnswer
from studyapp.platforms.rules import APPROVE, REJECT

NAME = "MTurk"
REGION = "us-east-1"  # MTurk's only region
PAGE_SIZE = 100
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
                return {"Assignments": [assignment for page in self._client.get_paginator(
                    xform_name(call.operation)).paginate(**call.body) for assignment in page["Assignments"]]}
            answer = operation(**call.body)
        except ClientError as error:
            details = error.response.get("Error", {})
            raise PlatformError(f"MTurk refused: {details.get('Message') or details.get('Code') or error}",
                                error.response.get("ResponseMetadata", {}).get("HTTPStatusCode")) from None
        except BotoCoreError as error:
            raise PlatformError(f"MTurk could not be reached at {self.address}: {error}") from None
        answer.pop("ResponseMetadata", None)
        return _plain(answer)

    def statuses(self, answer: dict) -> dict[str, str]:
        """Each assignment's status, by assignment id; PlatformError for a listing that names none."""
        listed = answer.get("Assignments")
        if not isinstance(listed, list) or not all(
                isinstance(a, dict) and isinstance(a.get("AssignmentId"), str) and isinstance(
                    a.get("AssignmentStatus", ""), str) for a in listed):
            raise UnconfirmedAnswer("MTurk's listing has an assignment without an id or a status")
        return {a["AssignmentId"]: a.get("AssignmentStatus", "") for a in listed}


def _plain(value: object) -> object:
    """An answer with its dates as text, so that it can be kept as JSON."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_plain(item) for item in value]
    return value if isinstance(value, str | int | float | bool | type(None)) else str(value)


__all__ = ["MTurkAPI", "NAME", "rejection_feedback"]
