"""``manage.py export_controls STUDY_ID --out DIR``: the study's controls as files, as the controls page's download."""

from pathlib import Path

from django.core.management.base import BaseCommand

from studyapp.stimuli.control_export import write_bundle
from studyapp.stimuli.controls import ControlError

from ._study import InputError, study_by_id


class Command(BaseCommand):
    help = ("Write every control of a study as files any code can read (paths as .npz, labels as JSON, an "
            "index.json and a README.txt saying what a submission of motion must look like).")

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("--out", type=Path, required=True, help="the folder to write (created)")
        parser.add_argument("--natural", action="store_true",
                            help="also the natural clips of the held-out controls as BVH (read where their takes are)")

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        out: Path = options["out"]
        if out.exists() and (not out.is_dir() or any(out.iterdir())):
            raise InputError(f"{out}: give a new or empty folder")
        try:
            written = write_bundle(study, out, options["natural"])
        except (ControlError, ValueError, FileNotFoundError) as error:
            raise InputError(str(error)) from None
        natural = " (natural clips as BVH in centimetres, y up)" if options["natural"] else ""
        self.stdout.write(f"{len(written)} files in {out}{natural}")
