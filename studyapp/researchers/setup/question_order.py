"""The order of a study's questions, each part (before the ratings, after them) on its own:
a new question or one moved to the other part comes last, and a question moves one place
up or down by swapping with its neighbour. Places are renumbered 0, 1, 2, ... on every
change, so questions of older studies (all at 0, in the order they were added) take the
order they were shown in."""

from __future__ import annotations

from django.db import transaction
from django.db.models import Max

from studyapp.models import Question


def last_place(question: Question) -> int:
    """The place after every other question of ``question``'s part."""
    others = Question.objects.filter(study=question.study_id, part=question.part).exclude(pk=question.pk)
    highest = others.aggregate(highest=Max("order"))["highest"]
    return 0 if highest is None else highest + 1


def move(question: Question, step: int) -> bool:
    """Move ``question`` ``step`` places (-1 up, +1 down) within its part; False where it
    is at that end already."""
    with transaction.atomic():
        part = list(Question.objects.select_for_update().filter(study=question.study_id, part=question.part))
        index = next(i for i, q in enumerate(part) if q.pk == question.pk)
        target = index + step
        if not 0 <= target < len(part):
            return False
        part[index], part[target] = part[target], part[index]
        for place, item in enumerate(part):
            if item.order != place:
                Question.objects.filter(pk=item.pk).update(order=place)
    return True


__all__ = ["last_place", "move"]
