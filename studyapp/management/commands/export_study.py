"""``manage.py export_study STUDY_ID --out study.zip``: the whole study as one bundle (``studyapp.bundles``)."""

from pathlib import Path

from django.core.management.base import BaseCommand

from studyapp.bundles.pseudonyms import export_key
from studyapp.bundles.writing import ExportError, write_study_bundle
from studyapp.stimuli.controls import ControlError

from ._study import InputError, study_by_id


class Command(BaseCommand):
    help = ("Write a study as one zip: its definition, checkpoints and submitted motion by digest, controls, "
            "sampled motion, ratings and participants (platform ids replaced by a keyed hash, no IP addresses), "
            "rules, the code version and a manifest of every file's SHA-256; optionally every clip's video. "
            "`import_study` re-creates it on another server.")

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("--out", type=Path, required=True, help="the zip to write")
        parser.add_argument("--with-videos", action="store_true", help="also every finished clip's video")
        parser.add_argument("--pseudonym-key-file", type=Path, metavar="FILE",
                            help="a file holding the key (at least 16 characters) that platform ids are hashed "
                                 "with, the same in every export that uses it; without it each export draws a "
                                 "random key that is written nowhere")

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        out: Path = options["out"]
        if out.suffix.lower() != ".zip":
            raise InputError(f"{out}: a bundle is a .zip file")
        if out.is_dir() or not out.parent.is_dir():
            raise InputError(f"{out}: give a file in an existing folder")
        given = None
        if key_file := options["pseudonym_key_file"]:
            try:
                given = key_file.read_text().strip()
            except (OSError, UnicodeDecodeError) as error:
                raise InputError(f"{key_file}: cannot read the key ({error})") from None
        try:
            manifest = write_study_bundle(study, out, export_key(given), options["with_videos"])
        except (ExportError, ControlError, ValueError) as error:
            raise InputError(str(error)) from None
        size = sum(entry.size for entry in manifest.files.values())
        self.stdout.write(f"{len(manifest.files) + 1} files ({size / 1e6:.1f} MB unpacked) in {out}")
