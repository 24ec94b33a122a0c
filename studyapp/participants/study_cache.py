"""Studies as the participant pages read them: kept in memory per process, read again when changed.

Every participant request needs its study (design, scale, rules, texts), and building it
with the participant's row (some 45 columns to select and convert) cost a rating step
more than any other query. Instead the participant's query reads the study's ``updated``
stamp alone, and the study comes from here while that stamp is unchanged: a researcher's
edit (``Study.save`` always stamps it) reaches every process on its next request.

The cached study is shared by the process's threads: callers read it and never change it.
"""

from __future__ import annotations

from datetime import datetime

from studyapp.models import Study

_studies: dict[int, Study] = {}


def current_study(pk: int, updated: datetime) -> Study:
    """The study ``pk`` as saved at ``updated``, from memory when this process has that version."""
    study = _studies.get(pk)
    if study is None or study.updated != updated:
        study = _studies[pk] = Study.objects.get(pk=pk)
    return study
