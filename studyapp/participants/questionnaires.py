"""The study's questions before the ratings (screening) and after them (demographics,
comments): reading a participant's answers from a form and judging the screening ones.

Answers are kept on the participant by question name (``Participant.answers``) and go
out with the participant list.
"""

from __future__ import annotations

import math

from django.http import QueryDict

from studyapp.models import Question, Study
from studyapp.participants.refusal import AnswerRefused

MAX_ANSWER_LENGTH = 2000


def questions(study: Study, part: str) -> list[Question]:
    return list(study.questions.filter(part=part))


def field_name(question: Question) -> str:
    """The form field of a question."""
    return f"q-{question.name}"


def _answer(question: Question, text: str) -> str | int | float:
    if question.kind == Question.Kind.CHOICE:
        if text not in question.choice_list:
            raise AnswerRefused(f"“{question.text}”: please choose one of the answers")
        return text
    if question.kind == Question.Kind.NUMBER:
        return _number(question, text)
    return text[:MAX_ANSWER_LENGTH]


def _number(question: Question, text: str) -> int | float:
    """A number answer within the question's bounds (a whole one where it asks for that).

    float() reads "nan", "inf" and 400 nines (as inf), none of which a JSON column stores
    or an analysis can use: every answer is finite and in range, or refused saying the range.
    """
    whole = question.whole_numbers
    wanted = (f"a whole number from {math.ceil(question.minimum)} to {math.floor(question.maximum)}" if whole
              else f"a number from {question.minimum:g} to {question.maximum:g}")
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and question.minimum <= value <= question.maximum) or (whole and value != int(value)):
        raise AnswerRefused(f"“{question.text}”: please give {wanted}, not {text[:20]!r}")
    return int(value) if whole else value


def read_answers(asked: list[Question], form: QueryDict) -> dict[str, str | float]:
    """The answers to ``asked`` in ``form``, or AnswerRefused (400) naming the first
    question left out or answered wrongly."""
    answers: dict[str, str | float] = {}
    for question in asked:
        text = form.get(field_name(question), "").strip()
        if not text:
            if question.required:
                raise AnswerRefused(f"“{question.text}”: please answer this question")
            continue
        answers[question.name] = _answer(question, text)
    return answers


def screened_out(asked: list[Question], answers: dict[str, str | float]) -> bool:
    """Whether an answer falls outside what a screening question accepts."""
    return any(question.accepted_list and answers.get(question.name) not in question.accepted_list
               for question in asked)


__all__ = ["field_name", "questions", "read_answers", "screened_out"]
