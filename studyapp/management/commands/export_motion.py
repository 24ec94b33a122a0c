"""``manage.py export_motion STUDY_ID --out DIR``: every system's motion of a study, one folder
per system, as ``python -m analysis objective DIR`` reads it."""

from pathlib import Path

from django.core.management.base import BaseCommand

from studyapp.stimuli.motion_export import exported_stimuli, write_motion

from ._study import InputError, study_by_id


class Command(BaseCommand):
    help = ("Write the motion of every finished clip of a study (sampled, submitted and natural) as .npz files, "
            "one folder per system named as in the ratings table, for `python -m analysis objective` and "
            "`python -m analysis report --motion`, and each clip as a rotation BVH on its system's rig (cm, y up) "
            "for animation tools.")

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("--out", type=Path, required=True, help="the folder to write (new or empty)")

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        out: Path = options["out"]
        if not exported_stimuli(study):
            raise InputError(f"study {study.pk} has no finished clip with motion yet: generate its stimuli first")
        try:
            counts = write_motion(study, out)
        except ValueError as error:
            raise InputError(str(error)) from None
        for system, clips in sorted(counts.items()):
            self.stdout.write(f"{system}: {clips} clip(s)")
        self.stdout.write(f"in {out}")
