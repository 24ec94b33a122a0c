"""How long a participant of a study takes: the time to advertise on the crowd platform
(Prolific asks for it and judges the pay by it).

    (pages + practice pages) x (clips on a page x a clip's length + answers on a page x ANSWER_S)
      + START_S for the consent and the instructions + QUESTION_S for each question

said in words on the settings' card (no formula: "8 clips and 4 practice clips, each with
1 clip of about 6.0 s to watch and 1 answer of about 5 s to give; ...").

The pages, practice pages and what a page shows and asks come from the study's design
(instructed checks are among the pages); a clip's length is the mean of the study's
finished clips other than BAD, or of its controls before any clip is finished.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from django.db.models import Avg

from studyapp.designs.registry import design_of
from studyapp.models import Stimulus, Study, System

ANSWER_S = 5.0  # to choose a rating, set a slider or pick a clip, after the clips have played
START_S = 60.0  # to read the consent and the instructions
QUESTION_S = 15.0  # to answer a question before or after the ratings


@dataclass(frozen=True)
class Duration:
    seconds: float
    how: str  # how it was computed, in words

    @property
    def minutes(self) -> int:
        """Whole minutes, rounded up: what to advertise."""
        return math.ceil(self.seconds / 60)


def expected_duration(study: Study) -> Duration | None:
    """The expected time of one participant; None before the study has clips or controls."""
    clip_s = (Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE).exclude(system__role=System.Role.BAD)
              .aggregate(mean=Avg("duration_s"))["mean"] or study.controls.aggregate(mean=Avg("seconds"))["mean"])
    if not clip_s:
        return None
    design = design_of(study)
    pages, practice = design.page_count(study), design.practice_page_count(study)
    clips, answers = design.clips_per_page(study), design.answers_per_page(study)
    questions = study.questions.count()
    seconds = (pages + practice) * (clips * clip_s + answers * ANSWER_S) + START_S + questions * QUESTION_S
    word = design.page_word.lower()
    asked = (f"; {QUESTION_S:g} s for {'the question' if questions == 1 else f'each of the {questions} questions'}"
             if questions else "")
    how = (f"{_counted(pages, word)} and {_counted(practice, 'practice ' + word)}, each with "
           f"{_counted(clips, 'clip')} of about {clip_s:.1f} s to watch and {_counted(answers, 'answer')} of about "
           f"{ANSWER_S:g} s to give; {START_S / 60:g} min for the consent and the instructions{asked}")
    return Duration(seconds, how)


def _counted(number: float, noun: str) -> str:
    """"1 clip", "3 clips", "2.5 clips on average" (a design whose pages differ)."""
    if number == int(number):
        return f"{int(number)} {noun}{'' if number == 1 else 's'}"
    return f"{number:.3g} {noun}s on average"
