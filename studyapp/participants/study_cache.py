"""Studies and their rendered clips as the participant pages read them: kept in memory per
process, read again when changed.

Every participant request needs its study (design, scale, rules, texts), and building it
with the participant's row (some 45 columns to select and convert) cost a rating step
more than any other query. Instead the participant's query reads the study's ``updated``
stamp alone, and the study comes from here while that stamp is unchanged: a researcher's
edit (``Study.save`` always stamps it) reaches every process on its next request.

Enrolment plans a participant's pages from the study's rendered clips (``rendered_clips``).
Reading them with their systems made some 250 objects per participant, a quarter of an
enrolment's CPU; instead it reads what a plan uses of them (ids, systems' roles, controls),
and builds the objects only when that has changed: a clip rendered or rendered again, a
system's role edited.

What is cached is shared by the process's threads: callers read it and never change it.
"""

from __future__ import annotations

from datetime import datetime

from studyapp.models import Stimulus, Study
from studyapp.server.db.compiled_queries import CompiledQuery

_studies: dict[int, Study] = {}
_rendered: dict[int, tuple[frozenset[tuple], list[Stimulus]]] = {}  # by study: what plans read of them, and the clips

_PLANNED_FIELDS = ("pk", "system_id", "system__role", "control_id", "shown_control_id")  # what plans read of a clip
_planned_fields = CompiledQuery(
    lambda study: Stimulus.objects.filter(study_id=study, status=Stimulus.Status.DONE).values_list(*_PLANNED_FIELDS),
    int)


def current_study(pk: int, updated: datetime) -> Study:
    """The study ``pk`` as saved at ``updated``, from memory when this process has that version."""
    study = _studies.get(pk)
    if study is None or study.updated != updated:
        study = _studies[pk] = Study.objects.get(pk=pk)
    return study


def rendered_clips(study: Study) -> list[Stimulus]:
    """The study's rendered clips with their systems, in their usual order; from memory
    while what a plan reads of them is unchanged."""
    planned = frozenset(_planned_fields(study.pk))
    cached = _rendered.get(study.pk)
    if cached is None or cached[0] != planned:
        clips = list(Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE).select_related("system"))
        cached = _rendered[study.pk] = (frozenset((s.pk, s.system_id, s.system.role, s.control_id, s.shown_control_id)
                                                  for s in clips), clips)
    return cached[1]
