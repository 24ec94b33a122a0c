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


def study_by_id_or_key(given: str) -> Study:
    """The study whose id or whose key (its entry link's) is ``given``."""
    study = Study.objects.filter(pk=int(given)).first() if given.isdigit() and len(given) < 10 else None
    study = study or Study.objects.filter(key=given).first()
    if study is None:
        raise InputError(f"no study with the id or key {given!r}")
    return study
