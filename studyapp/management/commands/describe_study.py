"""``manage.py describe_study STUDY [--out FILE]``: the study's definition as YAML, which
``create_study OWNER --from FILE`` makes into a study again."""

from pathlib import Path

from django.core.management.base import BaseCommand

from generation.files import atomic_output
from studyapp.definitions import definition_yaml
from studyapp.models import StoredDataError

from ._study import InputError, study_by_id_or_key


class Command(BaseCommand):
    help = ("Write a study's definition (its settings, questions, systems by checkpoint digest, controls) as YAML, "
            "to standard output or --out FILE.")

    def add_arguments(self, parser):
        parser.add_argument("study", help="the study's id or key (a key that begins with '-' after '--': "
                                                     "describe_study -- -KEY)")
        parser.add_argument("--out", type=Path, help="the file to write (default: standard output)")

    def handle(self, *args, **options):
        study = study_by_id_or_key(options["study"])
        try:
            text = definition_yaml(study)
        except StoredDataError as error:
            raise InputError(f"{error} (fix it in the admin: {error.admin_url})") from None
        if options["out"] is None:
            self.stdout.write(text, ending="")
            return
        out: Path = options["out"]
        if out.is_dir() or not out.parent.is_dir():
            raise InputError(f"{out}: give a file in an existing folder")
        try:
            with atomic_output(out) as tmp:
                tmp.write_text(text, encoding="utf-8")
        except OSError as error:
            raise InputError(f"{out}: cannot write it ({error.strerror or error})") from None
        self.stdout.write(f"{out}: the definition of study {study.pk}")
