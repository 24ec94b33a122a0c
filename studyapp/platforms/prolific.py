"""Prolific's API (docs.prolific.com, API reference): the calls a study's review needs.

    approve, reject   POST /api/v1/submissions/{id}/transition/   {"action": "APPROVE"} or
                      {"action": "REJECT", "message": (100 characters at least), "rejection_category": ...}
    request a return  POST /api/v1/submissions/{id}/request-return/   {"request_return_reasons": [...]}
    bonuses           POST /api/v1/submissions/bonus-payments/   {"study_id", "csv_bonuses": "<submission>,<amount>\\n..."}
                      then POST /api/v1/bulk-bonus-payments/{id}/pay/ with the id the first answered
    read back         GET /api/v1/studies/{study id}/submissions/   (pages followed)

A submission's id is the SESSION_ID Prolific puts in the entry link. Requests carry
``Authorization: Token <token>``; the token goes nowhere else: no redirect is followed,
and a listing's next page is followed only within Prolific's own address, each page once,
at most ``MAX_PAGES`` within ``READ_DEADLINE_S``. Prolific answers 400 for a request it
refuses (with its reason), 401 for a token it does not know, 404 for an id it does not
know and 429 when asked too often (then it is asked again after the wait it names:
``json_exchange``).

A call counts as done only when the answer confirms it: the status Prolific answers it
with (``CONFIRMING``), JSON without an error, and the same submission in the state asked
for, or the id of the bonus payment set up (which the payment then goes to). Any other
answer raises ``UnconfirmedAnswer``, so that the call stays undone and says so.
"""

from __future__ import annotations

import hashlib
import json
import time
from decimal import Decimal
from urllib.parse import urljoin, urlsplit

from django.conf import settings

from studyapp.platforms.calls import Call, Payee, PlatformError, UnconfirmedAnswer, is_platform_id
from studyapp.platforms.credentials import is_secret_text
from studyapp.platforms.json_exchange import Answer, exchange, shown
from studyapp.platforms.rules import APPROVE, REJECT, REQUEST_RETURN

NAME = "Prolific"
REJECTION_CATEGORY = "FAILED_CHECK"  # Prolific's category for failed attention checks
MIN_REJECTION_MESSAGE = 100  # characters, as Prolific requires of a rejection's message
REQUEST_DEADLINE_S = 60.0  # one request, the waits after a 429 included
READ_DEADLINE_S = 60.0  # every page of a listing
MAX_PAGES = 1000
MAX_STATUS_LENGTH = 40
# The statuses Prolific answers each call with when it did it, and the status a transition leaves.
CONFIRMING = {APPROVE: {200}, REJECT: {200}, REQUEST_RETURN: {200}, "bonus": {200, 201}, "pay bonus": {200, 202}}
TRANSITIONED = {APPROVE: "APPROVED", REJECT: "REJECTED"}


def rejection_message(failed_checks: int) -> str:
    """What a rejected participant reads: the reason in words, and where to turn."""
    checks = "an attention check" if failed_checks == 1 else f"{failed_checks} attention checks"
    return (f"Your submission is rejected because you did not answer {checks} as the page asked. Each of these "
            f"checks told you which answer to give (for example 'please answer 3'), whatever you thought of the "
            f"video. If you believe this is a mistake, please send the researcher a message.")


class ProlificAPI:
    name = NAME

    def __init__(self, token: str, base_url: str | None = None) -> None:
        if not is_secret_text(token):  # the forms and the session refuse it before: never sent, never quoted
            raise ValueError("a Prolific token is printable ASCII without spaces")
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
        """Send ``call`` (``answers``: earlier calls' answers by key, for one that needs them)
        and return Prolific's answer once it confirms the call; UnconfirmedAnswer if it does not."""
        try:
            return self._send(call, answers)
        except PlatformError as error:  # an answer that quotes the token back quotes it no further
            raise type(error)(str(error).replace(self._token, "[the token]"), error.status) from None

    def _send(self, call: Call, answers: dict[str, dict]) -> dict:
        method, path = call.operation.split(" ", 1)
        if call.after:
            payment = _payment_id(answers[call.after])
            if payment is None:
                raise PlatformError(f"the recorded answer to {call.after} names no bonus payment to pay: set the "
                                    f"bonuses up again on Prolific's pages")
            path = path.replace("{id}", payment)
        if method == "GET":
            return self._read_all(path)
        return _confirmed(call, self._request(method, self.address + path, call.body,
                                              time.monotonic() + REQUEST_DEADLINE_S))

    def statuses(self, answer: dict) -> dict[str, str]:
        """Each submission's status in a read-back answer (``_read_all``'s), by submission id."""
        return {submission["id"]: submission["status"] for submission in answer["results"]}

    def _read_all(self, path: str) -> dict:
        """Every page of a listing, joined: pages only of Prolific's own address, each once,
        at most MAX_PAGES of them within READ_DEADLINE_S."""
        deadline = time.monotonic() + READ_DEADLINE_S
        results: list[dict[str, str]] = []
        url: str | None = self.address + path
        asked: set[str] = set()
        while url:
            if url in asked:
                raise UnconfirmedAnswer(f"Prolific's listing links to a page it gave already ({shown(url)}): the "
                                        f"submissions were not read")
            if len(asked) == MAX_PAGES:
                raise UnconfirmedAnswer(f"Prolific's listing goes on past {MAX_PAGES} pages: the submissions were "
                                        f"not read")
            asked.add(url)
            page = self._request("GET", url, None, deadline)
            if page.status != 200:
                raise UnconfirmedAnswer(f"Prolific answered {page.status} to a listing, not 200: {page.text}",
                                        page.status)
            results += _listed(page.json, len(asked))
            url = self._next_page(page.json, url)  # a dict: _listed read it
        return {"results": results}

    def _next_page(self, page: dict, url: str) -> str | None:
        """The listing's next page, if it is one of Prolific's own (PlatformError otherwise)."""
        links = page.get("_links") or {}
        if not isinstance(links, dict):
            raise UnconfirmedAnswer("Prolific's listing has links that are not an object: the submissions were not "
                                    "read")
        following = links.get("next")
        href = following.get("href") if isinstance(following, dict) else following
        if href is None:
            return None
        if not isinstance(href, str):
            raise UnconfirmedAnswer(f"Prolific's listing names its next page as {shown(json.dumps(href))}, not an "
                                    f"address")
        target, own = urlsplit(urljoin(url, href)), urlsplit(self.address)
        if (target.scheme.lower(), target.netloc.lower()) != (own.scheme.lower(), own.netloc.lower()) or (
                not target.path.startswith(own.path + "/api/")):
            raise PlatformError(f"Prolific's listing names a next page outside {self.address} "
                                f"({shown(href)!r}): not followed, and the submissions were not read")
        return target.geturl()

    def _request(self, method: str, url: str, body: dict | None, deadline: float) -> Answer:
        """Prolific's 2xx answer; its refusal (4xx) raises PlatformError in its words."""
        answer = exchange(NAME, method, url, body if method != "GET" else None, {
            "Authorization": f"Token {self._token}", "Content-Type": "application/json",
            "Accept": "application/json"}, deadline)
        if answer.status >= 400:
            raise PlatformError(_refusal(answer), answer.status)
        return answer


def _payment_id(answer: object) -> str | None:
    """The id of the bonus payment that a set-up's answer names, if it names one fit for a path."""
    payment = answer.get("id") if isinstance(answer, dict) else None
    return payment if isinstance(payment, str) and is_platform_id(payment) else None


def _confirmed(call: Call, answer: Answer) -> dict:
    """Prolific's answer to ``call`` as it is kept, if it confirms what the call asked."""
    statuses = CONFIRMING[call.action]
    body = answer.json

    def unconfirmed(why: str) -> UnconfirmedAnswer:
        return UnconfirmedAnswer(f"Prolific answered {answer.status} {why}, which does not confirm it: "
                                 f"{answer.text}", answer.status)

    if answer.status not in statuses:
        raise unconfirmed(f"(not {' or '.join(map(str, sorted(statuses)))})")
    if isinstance(body, dict) and "error" in body:
        raise unconfirmed("with an error")
    if call.action == "pay bonus":  # Prolific answers with a sentence
        return body if isinstance(body, dict) else {"answer": body}
    if not isinstance(body, dict):
        raise unconfirmed("with JSON that is not an object")
    if call.action == "bonus":
        if _payment_id(body) is None:
            raise unconfirmed("without the id of the bonus payment")
        if body.get("study", call.body["study_id"]) != call.body["study_id"]:
            raise unconfirmed(f"for another study than {call.body['study_id']}")
        return body
    submission = call.key.partition(":")[2]
    if body.get("id") != submission:
        raise unconfirmed(f"about another submission than {submission}")
    if call.action in TRANSITIONED and body.get("status") != TRANSITIONED[call.action]:
        raise unconfirmed(f"with the status {shown(str(body.get('status')))}, not {TRANSITIONED[call.action]}")
    return body


def _listed(page: object, number: int) -> list[dict[str, str]]:
    """A listing page's submissions, each its id and status."""
    results = page.get("results") if isinstance(page, dict) else None
    if not isinstance(results, list):
        raise UnconfirmedAnswer(f"Prolific's listing (page {number}) has no list of results")
    listed = []
    for position, submission in enumerate(results, start=1):
        status = submission.get("status") if isinstance(submission, dict) else None
        if not (isinstance(submission, dict) and is_platform_id(submission.get("id")) and isinstance(status, str) and len(status) <= MAX_STATUS_LENGTH):
            raise UnconfirmedAnswer(f"Prolific's listing (page {number}, result {position}) is not a submission "
                                    f"with an id and a status")
        listed.append({"id": submission["id"], "status": status})
    return listed


def _refusal(answer: Answer) -> str:
    """Prolific's reason for refusing, in its words where it gave any."""
    text = answer.text
    if isinstance(answer.json, dict):
        detail = answer.json.get("error", answer.json)
        if isinstance(detail, dict):
            words = detail.get("detail") or detail.get("title") or detail
            text = shown(words if isinstance(words, str) else json.dumps(words))
    meaning = {401: "the token was not accepted (check it, or create another on Prolific)",
               404: "Prolific knows no such submission or study", 429: "asked too often; try again in a minute"}
    meant = f", {meaning[answer.status]}" if answer.status in meaning else ""
    return f"Prolific answered {answer.status}{meant}" + (f": {text}" if text else "")


__all__ = ["NAME", "ProlificAPI", "rejection_message"]
