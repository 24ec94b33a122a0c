"""``manage.py add_system STUDY_ID NAME CHECKPOINT``: register a system, as the systems page does."""

from pathlib import Path

from django.core.files import File
from django.core.management.base import BaseCommand

from generation.cli.common import add_unit_arguments
from studyapp.models import System
from studyapp.stimuli.submissions import Reading, add_submitted_system, add_submitted_upload, read_folder
from studyapp.stimuli.systems import UploadRefused, add_checkpoint_system, add_natural_system, add_video_system

from ._study import InputError, study_by_id


class Command(BaseCommand):
    help = ("Register a system: a checkpoint (role model or bad), the natural clips (--role natural, "
            "no file), submitted motion (--motion DIR_OR_ZIP) or videos (--video FILE ..., BAD unless --role model).")

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("name")
        parser.add_argument("checkpoint", nargs="?", help="a .safetensors checkpoint")
        parser.add_argument("--role", choices=System.Role.values, default=None,
                            help="model (default), bad or natural; videos default to bad")
        parser.add_argument("--temperature", type=float, default=1.0)
        parser.add_argument("--video", nargs="+", default=[], help="MP4 files")
        parser.add_argument("--motion", type=Path,
                            help="a folder or .zip of the lab's motion as it is: one BVH (any unit, y or z up, "
                                 "starting anywhere) or .npz per control, named by its id or ID_NN.bvh (see "
                                 "export_controls); the report says per control what was matched, converted and "
                                 "refused")
        parser.add_argument("--keep-root", action="store_true",
                            help="--motion: leave each clip where it was captured instead of moving its root's start "
                                 "to the control's (the origin, facing +z)")
        add_unit_arguments(parser, pairs=False)  # --motion's BVH files

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        name, checkpoint, videos, motion = options["name"], options["checkpoint"], options["video"], options["motion"]
        role = options["role"] or (System.Role.BAD if videos else System.Role.MODEL)
        if sum(map(bool, (checkpoint, videos, motion, role == System.Role.NATURAL))) != 1:
            raise InputError("give exactly one of: a checkpoint, --motion DIR_OR_ZIP, --video FILE ..., "
                             "or --role natural")
        for path in [checkpoint, *videos]:
            if path and not Path(path).is_file():
                raise InputError(f"{path}: no such file")
        if motion and not motion.exists():
            raise InputError(f"{motion}: no such folder or file")
        up = None if options["up"] == "auto" else options["up"]
        if (options["scale"] is not None or up is not None or options["keep_root"]) and not motion:
            raise InputError("--scale, --up and --keep-root say how --motion's files are read: give --motion")
        reading = Reading(options["scale"], up, options["keep_root"])
        try:
            if checkpoint:
                with File(Path(checkpoint).open("rb"), name=Path(checkpoint).name) as upload:
                    system = add_checkpoint_system(study, name, upload, role, options["temperature"])
            elif motion and motion.is_dir():
                system = add_submitted_system(study, name, read_folder(motion), role, motion.name, reading)
            elif motion:
                with File(motion.open("rb"), name=motion.name) as upload:
                    system = add_submitted_upload(study, name, upload, role, reading)
            elif videos:
                uploads = [File(Path(p).open("rb"), name=Path(p).name) for p in videos]
                try:
                    system = add_video_system(study, name, uploads, role)
                finally:
                    for upload in uploads:
                        upload.close()
            else:
                system = add_natural_system(study, name)
        except UploadRefused as error:
            raise InputError(str(error)) from None
        for line in system.metadata.get("report", []):
            self.stdout.write(line)
        self.stdout.write(f"{system.pk} {system}")
