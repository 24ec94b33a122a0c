"""What the study commands share: their error for bad input, finding the study an argument names."""

from django.core.management.base import CommandError

from studyapp.models import Study


class InputError(CommandError):
    """Bad input to a study command: its message, and exit status 2, as every command line of
    the project (Django's own CommandError exits with 1)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, returncode=2)


def study_by_id(study_id: int) -> Study:
    study = Study.objects.filter(pk=study_id).first()
    if study is None:
        raise InputError(f"no study with id {study_id}")
    return study
