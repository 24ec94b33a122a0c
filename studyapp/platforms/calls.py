"""One request to a crowd platform's API, as the dry run lists it and as it is sent.

A ``Call`` holds everything that goes out except the researcher's credentials: the
operation (Prolific: an HTTP method and path; MTurk: an API operation) and its body.
Its ``key`` says what it does to whom (``approve:<submission id>``), so that a call
whose key was done once is never sent again; its ``digest`` covers every field, so that
what is applied is exactly what the dry run showed.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import asdict, dataclass, field

# An id as the platforms give them (Prolific's 24 hex digits, MTurk's letters and digits)
# and as it may go into a request's path: one segment, never "../" or a query.
PLATFORM_ID = re.compile(r"[A-Za-z0-9_-]{1,100}")


def is_platform_id(text: object) -> bool:
    return isinstance(text, str) and PLATFORM_ID.fullmatch(text) is not None


@dataclass(frozen=True)
class Call:
    key: str  # what it does to whom; sent once
    action: str  # approve, reject, request return, bonus, pay bonus, read
    platform_id: str  # the participant it concerns ("" for the study as a whole)
    operation: str  # "POST /api/v1/…" (Prolific) or "ApproveAssignment" (MTurk)
    body: dict = field(default_factory=dict)  # sent as it is
    after: str = ""  # the key of the call whose answer it needs ({id} in the operation)

    @property
    def digest(self) -> str:
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()

    def shown(self) -> str:
        """The body as the dry run shows it."""
        return json.dumps(self.body, indent=1, ensure_ascii=False) if self.body else ""


@dataclass(frozen=True)
class Payee:
    """A participant as a platform knows them."""
    platform_id: str  # Prolific's PROLIFIC_PID, MTurk's workerId
    session: str  # their submission: Prolific's SESSION_ID, MTurk's assignmentId (from the entry link: checked)
    group: str  # what the submission belongs to: Prolific's STUDY_ID, MTurk's hitId


class PlatformError(Exception):
    """The platform refused or could not be reached; the message says why, in its words where it gave any."""

    def __init__(self, message: str, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status


class UnconfirmedAnswer(PlatformError):
    """The request went out, but the answer does not confirm that the platform did it (a
    server error, a redirect, an answer cut short, not JSON, not what the API answers):
    it may or may not have been done, so it is never recorded as done."""


__all__ = ["Call", "PLATFORM_ID", "Payee", "PlatformError", "UnconfirmedAnswer", "is_platform_id"]
