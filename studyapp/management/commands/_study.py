"""What the study commands share: finding the study an argument names."""

from django.core.management.base import CommandError

from studyapp.models import Study


def study_by_id(study_id: int) -> Study:
    study = Study.objects.filter(pk=study_id).first()
    if study is None:
        raise CommandError(f"no study with id {study_id}")
    return study
