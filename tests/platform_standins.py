"""Local stand-ins for the crowd platforms' APIs, served over HTTP on this machine.

``ProlificStandIn`` implements the endpoints of Prolific's API reference that a study's
review uses, with their documented rules and error answers: ``Authorization: Token``
(401 otherwise), 404 for an unknown id, 405 for a wrong method, 400 with a reason for a
refused request (a rejection message under 100 characters or without a known category, a
transition out of a final status, an empty return reason, bonuses for submissions of
another study, a bonus paid twice), the same transition twice answered as done (the
endpoint is idempotent), and listings in pages. ``MTurkStandIn`` answers MTurk's JSON
protocol (the X-Amz-Target header) for the operations the study uses, with MTurk's
RequestError for what it refuses and a refusal of requests signed with another access
key. Both record every request they get, for the tests to compare with the dry run.

Either can also misbehave as no real API should (``refuse_next``, ``misbehave``): answer
slowly, with a server error, with broken or cut JSON, with HTML, with bytes that are not
HTTP at all (``Raw``), with another submission's id, a redirect, or a listing whose next
page is itself, another host or a file. ``Elsewhere`` is another host, which records what
reaches it.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlparse


@dataclass(frozen=True)
class Raw:
    """Bytes written to the connection as they are in place of an answer (one that is not
    HTTP, or an HTTP answer cut short), after ``delay_s``; then the connection is closed."""
    data: bytes
    delay_s: float = 0.0


def http_answer(status: int, body: bytes, content_type: str = "application/json", length: int | None = None) -> bytes:
    """An HTTP answer's bytes, with a Content-Length of ``length`` (the body's own by default)."""
    head = (f"HTTP/1.1 {status} Whatever\r\nContent-Type: {content_type}\r\n"
            f"Content-Length: {len(body) if length is None else length}\r\nConnection: close\r\n\r\n")
    return head.encode() + body

REJECTION_CATEGORIES = {"TOO_QUICKLY", "TOO_SLOWLY", "FAILED_INSTRUCTIONS", "INCOMP_LONGITUDINAL", "FAILED_CHECK",
                        "LOW_EFFORT", "MALINGERING", "NO_CODE", "BAD_CODE", "NO_DATA", "UNSUPP_DEVICE", "OTHER"}
FINAL = {"APPROVED", "REJECTED", "RETURNED", "TIMED-OUT"}
PAGE_SIZE = 2  # small, so that reading back follows the pages


class StandIn:
    """An HTTP server in a thread; ``url`` is its address, ``requests`` what it was sent."""

    def __init__(self) -> None:
        self.requests: list[dict] = []
        # Answered before anything else, in turn: (status, body, headers) or Raw. A body of
        # bytes goes as it is, and headers may name another Content-Type.
        self.refuse_next: list[tuple[int, object, dict] | Raw] = []
        # Asked first about every request (method, path, body, headers): an answer, or None for the usual one.
        self.misbehave: Callable[[str, str, dict, object], tuple[int, object, dict] | Raw | None] | None = None
        stand_in = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args) -> None:  # quiet
                pass

            def _serve(self, method: str) -> None:
                length = int(self.headers.get("Content-Length") or 0)
                raw = self.rfile.read(length).decode() if length else ""
                body = json.loads(raw) if raw else {}
                stand_in.requests.append({"method": method, "path": self.path, "body": body,
                                          "headers": dict(self.headers)})
                answer = stand_in.misbehave(method, self.path, body, self.headers) if stand_in.misbehave else None
                if answer is None and stand_in.refuse_next:
                    answer = stand_in.refuse_next.pop(0)
                if answer is None:
                    answer = stand_in.answer(method, self.path, body, self.headers)
                if isinstance(answer, Raw):
                    time.sleep(answer.delay_s)
                    self.wfile.write(answer.data)
                    self.close_connection = True
                    return
                status, content, headers = answer
                payload = content if isinstance(content, bytes) else json.dumps(content).encode()
                self.send_response(status)
                self.send_header("Content-Type", headers.get("Content-Type", stand_in.content_type))
                self.send_header("Content-Length", str(len(payload)))
                for name, value in headers.items():
                    if name != "Content-Type":
                        self.send_header(name, value)
                self.end_headers()
                self.wfile.write(payload)

            def do_GET(self) -> None:
                self._serve("GET")

            def do_POST(self) -> None:
                self._serve("POST")

        self._server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self._server.server_address[1]}"
        # Polled every 10 ms rather than serve_forever's 0.5 s: shutting down waits for the
        # next poll, and every test of the platform pages stops a stand-in.
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.01},
                                        daemon=True)

    content_type = "application/json"

    def answer(self, method: str, path: str, body: dict, headers) -> tuple[int, object, dict]:
        raise NotImplementedError

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._server.shutdown()
        self._server.server_close()

    def sent(self, method: str | None = None) -> list[dict]:
        """The requests received, less reads unless ``method`` asks for them."""
        return [r for r in self.requests if (r["method"] == method if method else r["method"] != "GET")]


class Elsewhere(StandIn):
    """Another host: it answers 200 with ``answer_json`` to everything, and records what reaches it."""

    def __init__(self, answer_json: object) -> None:
        super().__init__()
        self.answer_json = answer_json

    def answer(self, method: str, path: str, body: dict, headers) -> tuple[int, object, dict]:
        return 200, self.answer_json, {}


def prolific_error(status: int, title: str, detail: object) -> tuple[int, dict, dict]:
    return status, {"error": {"status": status, "error_code": status * 1000, "title": title, "detail": detail}}, {}


class ProlificStandIn(StandIn):
    def __init__(self, token: str, submissions: dict[str, dict]) -> None:
        super().__init__()
        self.token = token
        self.submissions = submissions  # id -> {"id", "participant_id", "study_id", "status"}
        self.bulk_bonuses: dict[str, dict] = {}

    def answer(self, method: str, path: str, body: dict, headers) -> tuple[int, object, dict]:
        if headers.get("Authorization") != f"Token {self.token}":
            return prolific_error(401, "Unauthorized", "Invalid token.")
        url = urlparse(path)
        parts = [part for part in url.path.split("/") if part][2:]  # past api/v1
        routes = {
            ("submissions", "*", "transition"): ("POST", self._transition),
            ("submissions", "*", "request-return"): ("POST", self._request_return),
            ("submissions", "bonus-payments"): ("POST", self._bonus_setup),
            ("bulk-bonus-payments", "*", "pay"): ("POST", self._bonus_pay),
            ("studies", "*", "submissions"): ("GET", self._listing),
        }
        for pattern, (allowed, handle) in routes.items():
            if len(pattern) == len(parts) and all(p in ("*", part) for p, part in zip(pattern, parts)):
                if method != allowed:
                    return prolific_error(405, "Method Not Allowed", f"Method {method} not allowed.")
                ids = [part for p, part in zip(pattern, parts) if p == "*"]
                return handle(*ids, body=body, query=parse_qs(url.query))
        return prolific_error(404, "Not Found", "Not found.")

    def _submission(self, submission_id: str) -> dict | None:
        return self.submissions.get(submission_id)

    def _transition(self, submission_id: str, body: dict, query: dict):
        submission = self._submission(submission_id)
        if submission is None:
            return prolific_error(404, "Not Found", f"Submission {submission_id} not found.")
        action = body.get("action")
        target = {"APPROVE": "APPROVED", "REJECT": "REJECTED"}.get(action)
        if target is None:
            return prolific_error(400, "Bad Request", {"action": [f"{action!r} is not a valid choice."]})
        if action == "REJECT":
            if len(body.get("message", "")) < 100:
                return prolific_error(400, "Bad Request", {"message": ["Ensure this field has at least 100 characters."]})
            if body.get("rejection_category") not in REJECTION_CATEGORIES:
                return prolific_error(400, "Bad Request", {"rejection_category": ["Not a valid choice."]})
        if submission["status"] == target:  # the same request again is ignored
            return 200, submission, {}
        if submission["status"] in FINAL:
            return prolific_error(400, "Bad Request", f"Cannot transition a submission with status "
                                                      f"{submission['status']}.")
        submission["status"] = target
        return 200, submission, {}

    def _request_return(self, submission_id: str, body: dict, query: dict):
        submission = self._submission(submission_id)
        if submission is None:
            return prolific_error(404, "Not Found", f"Submission {submission_id} not found.")
        reasons = body.get("request_return_reasons")
        if not reasons or not all(isinstance(reason, str) and reason for reason in reasons):
            return prolific_error(400, "Bad Request", {"request_return_reasons": ["This field is required."]})
        submission["return_requested"] = "2026-01-01T00:00:00Z"
        submission["return_reasons"] = reasons
        return 200, {"id": submission["id"], "status": submission["status"], "participant": submission["participant_id"],
                     "return_requested": submission["return_requested"]}, {}

    def _bonus_setup(self, body: dict, query: dict):
        study_id, lines = body.get("study_id"), body.get("csv_bonuses", "")
        rows = [line.split(",") for line in lines.splitlines() if line.strip()]
        wrong = [row[0] for row in rows if self.submissions.get(row[0], {}).get("study_id") != study_id]
        if not rows or wrong:
            return prolific_error(400, "Bad Request", f"Invalid IDs: {', '.join(wrong) or 'none given'}")
        bulk_id = f"bulk-{len(self.bulk_bonuses) + 1}"
        amount = sum(round(float(row[1]) * 100) for row in rows)
        self.bulk_bonuses[bulk_id] = {"id": bulk_id, "study": study_id, "amount": amount, "fees": amount // 3,
                                      "total_amount": amount + amount // 3, "rows": rows, "paid": False}
        return 201, {key: value for key, value in self.bulk_bonuses[bulk_id].items() if key != "paid"}, {}

    def _bonus_pay(self, bulk_id: str, body: dict, query: dict):
        bulk = self.bulk_bonuses.get(bulk_id)
        if bulk is None:
            return prolific_error(404, "Not Found", f"Bonus payment {bulk_id} not found.")
        if bulk["paid"]:
            return prolific_error(400, "Bad Request", "This bonus payment has already been paid.")
        bulk["paid"] = True
        return 202, "The request to pay bonuses has been made successfully.", {}

    def _listing(self, study_id: str, body: dict, query: dict):
        listed = [s for s in self.submissions.values() if s["study_id"] == study_id]
        page = int(query.get("page", ["1"])[0])
        chunk = listed[(page - 1) * PAGE_SIZE: page * PAGE_SIZE]
        more = page * PAGE_SIZE < len(listed)
        following = {"href": f"{self.url}/api/v1/studies/{study_id}/submissions/?page={page + 1}"} if more else None
        return 200, {"results": [{key: s[key] for key in ("id", "participant_id", "status")} for s in chunk],
                     "_links": {"next": following}, "meta": {"count": len(listed)}}, {}


class MTurkStandIn(StandIn):
    content_type = "application/x-amz-json-1.1"

    def __init__(self, access_key_id: str, assignments: dict[str, dict]) -> None:
        super().__init__()
        self.access_key_id = access_key_id
        self.assignments = assignments  # id -> {"AssignmentId", "WorkerId", "HITId", "AssignmentStatus"}
        self.bonuses: list[dict] = []

    def answer(self, method: str, path: str, body: dict, headers) -> tuple[int, object, dict]:
        if f"Credential={self.access_key_id}/" not in headers.get("Authorization", ""):
            return 400, {"__type": "UnrecognizedClientException", "message": "The security token is invalid."}, {}
        operation = headers.get("X-Amz-Target", "").rpartition(".")[2]
        handle = {"ApproveAssignment": self._approve, "RejectAssignment": self._reject, "SendBonus": self._bonus,
                  "ListAssignmentsForHIT": self._listing}.get(operation)
        if handle is None:
            return 400, {"__type": "RequestError", "Message": f"Unknown operation {operation}"}, {}
        return handle(body)

    @staticmethod
    def _refusal(message: str):
        return 400, {"__type": "RequestError", "Message": message, "TurkErrorCode": "AWS.MechanicalTurk.Refused"}, {}

    def _decide(self, body: dict, status: str):
        assignment = self.assignments.get(body.get("AssignmentId", ""))
        if assignment is None:
            return self._refusal(f"Assignment {body.get('AssignmentId')} does not exist.")
        if assignment["AssignmentStatus"] != "Submitted":
            return self._refusal("This operation can be called with a status of: Submitted")
        assignment["AssignmentStatus"] = status
        assignment["RequesterFeedback"] = body.get("RequesterFeedback", "")
        return 200, {}, {}

    def _approve(self, body: dict):
        return self._decide(body, "Approved")

    def _reject(self, body: dict):
        if not body.get("RequesterFeedback"):
            return self._refusal("RequesterFeedback is required to reject an assignment.")
        return self._decide(body, "Rejected")

    def _bonus(self, body: dict):
        assignment = self.assignments.get(body.get("AssignmentId", ""))
        if assignment is None or assignment["WorkerId"] != body.get("WorkerId"):
            return self._refusal("The worker did not work on that assignment.")
        if not body.get("Reason"):
            return self._refusal("Reason is required.")
        if any(bonus["UniqueRequestToken"] == body.get("UniqueRequestToken") for bonus in self.bonuses):
            return self._refusal("The bonus with this UniqueRequestToken was already paid.")
        self.bonuses.append(body)
        return 200, {}, {}

    def _listing(self, body: dict):
        listed = [{key: a[key] for key in ("AssignmentId", "WorkerId", "HITId", "AssignmentStatus")}
                  for a in self.assignments.values() if a["HITId"] == body.get("HITId")]
        start = int(body.get("NextToken") or 0)
        chunk = listed[start:start + PAGE_SIZE]
        answer = {"NumResults": len(chunk), "Assignments": chunk}
        if start + PAGE_SIZE < len(listed):
            answer["NextToken"] = str(start + PAGE_SIZE)
        return 200, answer, {}
