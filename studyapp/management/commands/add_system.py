"""``manage.py add_system STUDY_ID NAME CHECKPOINT``: register a system, as the systems page does."""

from pathlib import Path

from django.core.files import File
from django.core.management.base import BaseCommand, CommandError

from studyapp.models import System
from studyapp.systems import UploadRefused, add_checkpoint_system, add_natural_system, add_video_system

from ._study import study_by_id


class Command(BaseCommand):
    help = ("Register a system: a checkpoint (role model or bad), the natural clips (--role natural, "
            "no file) or BAD videos (--video FILE ...).")

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("name")
        parser.add_argument("checkpoint", nargs="?", help="a .safetensors checkpoint")
        parser.add_argument("--role", choices=System.Role.values, default=System.Role.MODEL)
        parser.add_argument("--temperature", type=float, default=1.0)
        parser.add_argument("--video", nargs="+", default=[], help="MP4 files of a BAD system")

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        name, role, checkpoint, videos = options["name"], options["role"], options["checkpoint"], options["video"]
        if sum(map(bool, (checkpoint, videos, role == System.Role.NATURAL))) != 1:
            raise CommandError("give exactly one of: a checkpoint, --video FILE ..., or --role natural")
        for path in [checkpoint, *videos]:
            if path and not Path(path).is_file():
                raise CommandError(f"{path}: no such file")
        try:
            if checkpoint:
                with File(Path(checkpoint).open("rb"), name=Path(checkpoint).name) as upload:
                    system = add_checkpoint_system(study, name, upload, role, options["temperature"])
            elif videos:
                uploads = [File(Path(p).open("rb"), name=Path(p).name) for p in videos]
                try:
                    system = add_video_system(study, name, uploads)
                finally:
                    for upload in uploads:
                        upload.close()
            else:
                system = add_natural_system(study, name)
        except UploadRefused as error:
            raise CommandError(str(error)) from None
        self.stdout.write(f"{system.pk} {system}")
