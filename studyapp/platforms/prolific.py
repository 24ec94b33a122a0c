"""Prolific's API (docs.prolific.com, API reference): the calls a study's review needs.

    approve, reject   POST /api/v1/submissions/{id}/transition/   {"action": "APPROVE"} or
                      {"action": "REJECT", "message": (100 characters at least), "rejection_category": ...}
    request a return  POST /api/v1/submissions/{id}/request-return/   {"request_return_reasons": [...]}
    bonuses           POST /api/v1/submissions/bonus-payments/   {"study_id", "csv_bonuses": "<submission>,<amount>\\n..."}
                      then POST /api/v1/bulk-bonus-payments/{id}/pay/ with the id the first answered
    read back         GET /api/v1/studies/{study id}/submissions/   (pages followed)

A submission's id is the SESSION_ID Prolific puts in the entry link. Requests carry
``Authorization: Token <token>``; the token goes nowhere else. Prolific answers 400 for a
request it refuses (with its reason), 401 for a token it does not know, 404 for an id it
does not know and 429 when asked too often (then it is asked again after the wait it names,
up to ``RATE_LIMIT_RETRIES`` times).
"""

from __future__ import annotations

import hashlib
import json
import time
import urllib.error
import urllib.request
from decimal import Decimal

from django.conf import settings

from studyapp.platforms.calls import Call, Payee, PlatformError
from studyapp.platforms.rules import APPROVE, REJECT, REQUEST_RETURN

NAME = "Prolific"
REJECTION_CATEGORY = "FAILED_CHECK"  # Prolific's category for failed attention checks
MIN_REJECTION_MESSAGE = 100  # characters, as Prolific requires of a rejection's message
RATE_LIMIT_RETRIES, LONGEST_WAIT_S = 2, 10.0
TIMEOUT_S = 30.0


def rejection_message(failed_checks: int) -> str:
    """What a rejected participant reads: the reason in words, and where to turn."""
    checks = "an attention check" if failed_checks == 1 else f"{failed_checks} attention checks"
    return (f"Your submission is rejected because you did not answer {checks} as the page asked. Each of these "
            f"checks told you which answer to give (for example 'please answer 3'), whatever you thought of the "
            f"video. If you believe this is a mistake, please send the researcher a message.")


class ProlificAPI:
    name = NAME

    def __init__(self, token: str, base_url: str | None = None) -> None:
        self._token = token
        self.address = (base_url or settings.PROLIFIC_API_URL).rstrip("/")

    # What will be sent (the dry run)

    def decision(self, payee: Payee, action: str, failed_checks: int, why: str) -> Call | None:
        path = f"/api/v1/submissions/{payee.session}"
        if action == APPROVE:
            return Call(f"approve:{payee.session}", action, payee.platform_id, f"POST {path}/transition/",
                        {"action": "APPROVE"})
        if action == REJECT:
            return Call(f"reject:{payee.session}", action, payee.platform_id, f"POST {path}/transition/",
                        {"action": "REJECT", "message": rejection_message(failed_checks),
                         "rejection_category": REJECTION_CATEGORY})
        if action == REQUEST_RETURN:
            return Call(f"request-return:{payee.session}", action, payee.platform_id, f"POST {path}/request-return/",
                        {"request_return_reasons": [why]})
        return None

    def bonuses(self, amounts: list[tuple[Payee, Decimal]], reason: str) -> list[Call]:
        """One bonus payment per Prolific study: set up, then paid (Prolific has no reason field)."""
        calls = []
        for study_id in sorted({payee.group for payee, _ in amounts}):
            lines = "".join(f"{payee.session},{amount}\n" for payee, amount in amounts if payee.group == study_id)
            batch = hashlib.sha256(f"{study_id}\n{lines}".encode()).hexdigest()[:16]  # the same list: the same payment
            setup = Call(f"bonus:{study_id}:{batch}", "bonus", "", "POST /api/v1/submissions/bonus-payments/",
                         {"study_id": study_id, "csv_bonuses": lines})
            calls += [setup, Call(f"pay-bonus:{study_id}:{batch}", "pay bonus", "",
                                  "POST /api/v1/bulk-bonus-payments/{id}/pay/", after=setup.key)]
        return calls

    def reads(self, groups: list[str]) -> list[Call]:
        return [Call(f"read:{study_id}", "read", "", f"GET /api/v1/studies/{study_id}/submissions/")
                for study_id in sorted(groups)]

    # Sending

    def send(self, call: Call, answers: dict[str, dict]) -> dict:
        """Send ``call`` (``answers``: earlier calls' answers by key, for one that needs them)."""
        method, path = call.operation.split(" ", 1)
        if call.after:
            path = path.replace("{id}", str(answers[call.after]["id"]))
        if method == "GET":
            return self._read_all(path)
        return self._request(method, self.address + path, call.body)

    def statuses(self, answer: dict) -> dict[str, str]:
        """Each submission's status in a read-back answer, by submission id."""
        return {submission["id"]: submission.get("status", "") for submission in answer.get("results", [])}

    def _read_all(self, path: str) -> dict:
        """Every page of a listing, joined."""
        results, url = [], self.address + path
        while url:
            page = self._request("GET", url, None)
            results += page.get("results", [])
            url = (page.get("_links", {}).get("next") or {}).get("href")
        return {"results": results}

    def _request(self, method: str, url: str, body: dict | None) -> dict:
        data = json.dumps(body).encode() if body is not None and method != "GET" else None
        request = urllib.request.Request(url, data=data, method=method, headers={
            "Authorization": f"Token {self._token}", "Content-Type": "application/json", "Accept": "application/json"})
        for attempt in range(RATE_LIMIT_RETRIES + 1):
            try:
                with urllib.request.urlopen(request, timeout=TIMEOUT_S) as response:
                    text = response.read().decode()
                    return json.loads(text) if text.strip().startswith(("{", "[")) else {"answer": text}
            except urllib.error.HTTPError as error:
                if error.code == 429 and attempt < RATE_LIMIT_RETRIES:
                    time.sleep(min(float(error.headers.get("Retry-After") or 1), LONGEST_WAIT_S))
                    continue
                raise PlatformError(_refusal(error), error.code) from None
            except (urllib.error.URLError, TimeoutError, OSError) as error:
                raise PlatformError(f"Prolific could not be reached at {self.address}: "
                                    f"{getattr(error, 'reason', error)}") from None
        raise AssertionError("unreachable")


def _refusal(error: urllib.error.HTTPError) -> str:
    """Prolific's reason for refusing, in its words where it gave any."""
    text = error.read().decode(errors="replace")
    try:
        answer = json.loads(text)
    except ValueError:
        answer = None
    if isinstance(answer, dict):
        detail = answer.get("error", answer)
        if isinstance(detail, dict):
            words = detail.get("detail") or detail.get("title") or detail
            text = words if isinstance(words, str) else json.dumps(words)
    meaning = {401: "the token was not accepted (check it, or create another on Prolific)",
               404: "Prolific knows no such submission or study", 429: "asked too often; try again in a minute"}
    return f"Prolific answered {error.code}" + (f", {meaning[error.code]}" if error.code in meaning else "") + (
        f": {text[:300]}" if text else "")


__all__ = ["NAME", "ProlificAPI", "rejection_message"]
