"""``manage.py add_controls STUDY_ID``: held-out and synthetic controls, as the controls page adds them."""

from pathlib import Path

from django.core.files import File
from django.core.management.base import BaseCommand

from generation.cli.common import add_unit_arguments
from studyapp.stimuli.controls import (ControlError, add_control_file, add_held_out_controls, add_label_controls,
                                      add_preset_controls, shorter_than_asked_warnings)

from ._study import InputError, study_by_id


class Command(BaseCommand):
    help = ("Add control signals to a study: held-out takes of MOTION_DATA (or --folder), which NAT shows; for "
            "path-controlled models presets or JSON/YAML descriptions, for label-controlled ones (HVRNN, ERD, "
            "QuaterNet) pairs of actions and styles. In a study with checkpoints the held-out takes are those their "
            "training held out of the data they were trained on; in a study without, those the seeded split that "
            "training would make holds out of any folder, or the takes named with --takes.")

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("--held-out", type=float, metavar="SECONDS", help="held-out controls cut to SECONDS")
        parser.add_argument("--count", type=int, help="how many held-out controls (default: all)")
        parser.add_argument("--lead-in", type=float, default=0.0, metavar="SECONDS",
                            help="start each held-out clip SECONDS into its take; path-controlled models warm up on "
                                 "the take's control before it and NAT shows the same frames (default 0: the take's start)")
        parser.add_argument("--folder", nargs="+", metavar="DIR",
                            help="held-out takes of these motion folders, pooled (default: MOTION_DATA); with "
                                 "checkpoints, the data they were trained on")
        parser.add_argument("--takes", nargs="+", metavar="NAME",
                            help="held-out controls of these takes (file names without .bvh) instead of those the "
                                 "seeded split holds out; with checkpoints, among those their training held out")
        add_unit_arguments(parser, pairs=False)  # of the held-out takes, in a study without checkpoints
        parser.add_argument("--preset", nargs="+", default=[], help="names from generation.control.PRESETS")
        parser.add_argument("--file", nargs="+", default=[], help="JSON or YAML path descriptions")
        parser.add_argument("--actions", nargs="+", default=[], help="label controls: these actions ...")
        parser.add_argument("--styles", nargs="+", default=[], help="... each with each of these styles")
        parser.add_argument("--seconds", type=float, default=4.0, help="length of label controls (default 4)")

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        if not (options["held_out"] or options["preset"] or options["file"] or options["actions"] or options["styles"]):
            raise InputError("nothing to add: give --held-out SECONDS, --preset NAME ..., --file PATH ... "
                             "or --actions A ... --styles S ...")
        choosing = options["folder"] or options["takes"] or options["scale"] is not None or options["up"] != "auto"
        if choosing and not options["held_out"]:
            raise InputError("--folder, --takes, --scale and --up choose the held-out takes: give --held-out SECONDS")
        added = []
        try:
            held_out = add_held_out_controls(study, options["held_out"], options["count"], options["lead_in"],
                                             options["folder"], options["takes"], options["scale"],
                                             None if options["up"] == "auto" else options["up"]
                                             ) if options["held_out"] else []
            added += held_out
            if options["preset"]:
                added += add_preset_controls(study, options["preset"])
            if options["actions"] or options["styles"]:
                added += add_label_controls(study, options["actions"], options["styles"], options["seconds"])
            for path in options["file"]:
                if not Path(path).is_file():
                    raise InputError(f"{path}: no such file")
                with File(Path(path).open("rb"), name=Path(path).name) as upload:
                    added += add_control_file(study, upload)
        except ControlError as error:
            raise InputError(str(error)) from None
        for control in added:
            self.stdout.write(f"{control.pk} {control}")
        for warning in shorter_than_asked_warnings(held_out, options["held_out"]):
            self.stderr.write(f"warning: {warning}")
