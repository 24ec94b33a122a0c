"""The one way a participant's form is refused: an answer (a rating, a page, a questionnaire,
the device check) that must not be stored, with the HTTP status to answer with.

``participants.views.participant_access`` turns it into a plain page with the message
and a link back, having changed nothing.
"""


class AnswerRefused(Exception):
    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status
