"""``manage.py backup FOLDER [--list-files-only]``: the deployment's database and files as one folder
(``studyapp.backups``), written while the study runs; ``restore`` brings it back."""

from pathlib import Path

from django.core.management.base import BaseCommand

from studyapp.backups.backup import write_backup
from studyapp.backups.database import DatabaseError
from studyapp.backups.files import backed_up_folders
from studyapp.server.media_bucket import in_bucket

from ._study import InputError


class Command(BaseCommand):
    help = ("Write a backup folder: the database in one consistent snapshot (pg_dump, or SQLite's online backup), "
            "a copy of every clip, report, checkpoint and sampled motion file, and backup.json listing each file's "
            "size and SHA-256. `restore` brings it back into an empty database.")

    def add_arguments(self, parser):
        parser.add_argument("folder", type=Path, help="the backup folder to write (it must not exist yet)")
        parser.add_argument("--list-files-only", action="store_true",
                            help="list the files in backup.json without copying them, where the media and var "
                                 "volumes are kept by other means (a volume snapshot, rsync)")

    def handle(self, *args, **options):
        out: Path = options["folder"]
        if in_bucket():  # a backup without the clips would restore a study that cannot be shown
            raise InputError("no backup written: the clips are in the bucket of MEDIA_BUCKET_URL, which a backup "
                             "does not copy yet; back the bucket up with its provider's tools (docs/deploying.md)")
        if out.exists() or not out.parent.is_dir():
            raise InputError(f"{out}: give a folder that does not exist yet, in an existing folder")
        for name, root in backed_up_folders().items():
            if out.resolve().is_relative_to(root.resolve()):
                raise InputError(f"{out}: inside the {name} folder ({root}), which the backup copies; "
                                 "write it elsewhere")
        try:
            manifest = write_backup(out, copy_files=not options["list_files_only"])
        except DatabaseError as error:
            raise InputError(f"no backup written: {error}") from None
        except OSError as error:  # a folder that cannot be written (read-only, full, a system folder)
            raise InputError(f"no backup written in {out}: {error.strerror or error}") from None
        size = sum(entry.size for entry in manifest.files)
        kept = "listed" if options["list_files_only"] else "copied"
        self.stdout.write(f"the {manifest.engine} database and {len(manifest.files)} files ({size / 1e6:.1f} MB, "
                          f"{kept}) backed up in {out}")
