"""The language of a study's participant pages: the study's setting (``Study.language``),
never the browser's, and English wherever no study is known.

A participant view runs inside ``participant_language()``; ``speak(study)`` switches to the
study's language as soon as its row is read, so that the page, its messages and its
refusals (raised with their words in that language) all come in it, and the language the
thread had before comes back when the view returns. Only the app's own words are
translated: the researcher's texts (title, instructions, consent, question, scale labels,
questions) are shown as they were written.
"""

from __future__ import annotations

from contextlib import AbstractContextManager

from django.conf import settings
from django.utils import translation

from studyapp.models import Study


def participant_language() -> AbstractContextManager:
    """The project's language (English) until ``speak`` names a study's; the thread's own afterwards."""
    return translation.override(settings.LANGUAGE_CODE)


def speak(study: Study) -> Study:
    """Speak ``study``'s language for the rest of the request (inside ``participant_language()``,
    or a ``translation.override`` of the caller's); returns the study."""
    translation.activate(study.language)
    return study


__all__ = ["participant_language", "speak"]
