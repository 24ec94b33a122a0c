"""Django app configuration for the study app."""

from django.apps import AppConfig


class StudyappConfig(AppConfig):
    name = "studyapp"
    verbose_name = "Motion rating study"

    def ready(self) -> None:
        from studyapp.preregistration import lock

        lock.connect()  # opening a study locks its plan; later changes are recorded as deviations
