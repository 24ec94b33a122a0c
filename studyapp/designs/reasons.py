"""Reasons with a page's answer (the study's ``reasons``): why the participant answered as
they did, as GENEA asks after each vote.

A page of a study with reasons shows each as a checkbox with its own label, and "Other"
with a text field for the participant's own words; with ``reasons_required`` the answer
needs at least one of them. The form sends the ticked reasons by their number in the
study's list (``reason``, from 1), so a reason's words never travel back from the
browser; "Other" is its text (``other_reason``), stripped, with any markup taken out and
at most ``Rating.other_reason``'s length. A reason the list lacks, "Other" ticked with
no words, or words longer than allowed is refused (400) with what is wrong; a study
without reasons refuses them. Every rating of the page stores them (``Rating.reasons``,
``other_reason``), and the export writes them in GENEA's columns
(``analysis.reports.reasons``).
"""

from __future__ import annotations

import re

from django.http import QueryDict
from django.utils.html import strip_tags

from studyapp.models import Rating, Study
from studyapp.participants.refusal import AnswerRefused

REASON_FIELD, OTHER_BOX, OTHER_FIELD = "reason", "other", "other_reason"
MAX_OTHER_CHARS = Rating._meta.get_field("other_reason").max_length
_SPACE = re.compile(r"\s+")


def plain_text(text: str) -> str:
    """Words a participant typed as plain text on one line: markup taken out, any < or >
    left dropped, runs of white space (line breaks, tabs) one space, ends stripped."""
    return _SPACE.sub(" ", strip_tags(text).replace("<", "").replace(">", "")).strip()


def read_reasons(study: Study, form: QueryDict) -> tuple[tuple[str, ...], str]:
    """The reasons a page's form sent, in the study's words and order, and the "Other"
    words ("" for none); AnswerRefused for what the study's list cannot hold."""
    listed = study.reason_list
    numbers = form.getlist(REASON_FIELD)
    typed = form.get(OTHER_FIELD, "")
    if not listed:
        if numbers or typed.strip() or form.get(OTHER_BOX):
            raise AnswerRefused("this study asks for no reasons")
        return (), ""
    chosen = set()
    for number in numbers:
        if not (number.isascii() and number.isdigit() and 1 <= int(number) <= len(listed)):
            raise AnswerRefused(f"a reason is one of the {len(listed)} listed, by its number; not {number[:20]!r}")
        chosen.add(int(number))
    if len(typed) > MAX_OTHER_CHARS:
        raise AnswerRefused(f"the other reason is at most {MAX_OTHER_CHARS} characters, not {len(typed)}")
    other = plain_text(typed)
    if form.get(OTHER_BOX) and not other:
        raise AnswerRefused('please say in a few words what the other reason is, or untick "Other"')
    return tuple(listed[n - 1] for n in sorted(chosen)), other


def check_reasons(study: Study, reasons: tuple[str, ...], other: str) -> None:
    """Refuse an answer without a reason where the study requires one."""
    if study.reason_list and study.reasons_required and not reasons and not other:
        raise AnswerRefused('please tick at least one reason for your answer (or "Other" with a few words)')


def reasons_context(study: Study) -> dict:
    """The page's reasons as plain data: each with its number, and whether one is required."""
    return {"reasons": [{"number": n, "text": text} for n, text in enumerate(study.reason_list, start=1)],
            "reasons_required": study.reasons_required and bool(study.reason_list),
            "other_max": MAX_OTHER_CHARS}
