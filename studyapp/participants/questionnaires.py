"""The study's questions before the ratings (screening) and after them (demographics,
comments): reading a participant's answers from a form and judging the screening ones.

Answers are kept on the participant by question name (``Participant.answers``) and go
out with the participant list.
"""

from __future__ import annotations

import math

from django.http import QueryDict
from django.utils.translation import gettext as _

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
            raise AnswerRefused(_("“%(question)s”: please choose one of the answers") % {"question": question.text})
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
    wanted = (_("a whole number from %(low)s to %(high)s") % {"low": math.ceil(question.minimum),
                                                                "high": math.floor(question.maximum)} if whole
              else _("a number from %(low)s to %(high)s") % {"low": f"{question.minimum:g}",
                                                             "high": f"{question.maximum:g}"})
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and question.minimum <= value <= question.maximum) or (whole and value != int(value)):
        raise AnswerRefused(_("“%(question)s”: please give %(wanted)s, not %(given)s")
                            % {"question": question.text, "wanted": wanted, "given": repr(text[:20])})
    return int(value) if whole else value


def read_answers(asked: list[Question], form: QueryDict) -> dict[str, str | float]:
    """The answers to ``asked`` in ``form``, or AnswerRefused (400) naming the first
    question left out or answered wrongly."""
    answers: dict[str, str | float] = {}
    for question in asked:
        text = form.get(field_name(question), "").strip()
        if not text:
            if question.required:
                raise AnswerRefused(_("“%(question)s”: please answer this question") % {"question": question.text})
            continue
        answers[question.name] = _answer(question, text)
    return answers


def screened_out(asked: list[Question], answers: dict[str, str | float]) -> bool:
    """Whether an answer falls outside what a screening question accepts."""
    return any(question.accepted_list and answers.get(question.name) not in question.accepted_list
               for question in asked)


__all__ = ["field_name", "questions", "read_answers", "screened_out"]
