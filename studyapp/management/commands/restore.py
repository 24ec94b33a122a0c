"""``manage.py restore FOLDER``: a backup written by ``backup`` brought back into an empty database
and the deployment's folders, every file checked against its manifest first."""

from pathlib import Path

from django.core.management.base import BaseCommand

from studyapp.backups.database import DatabaseError
from studyapp.backups.manifest import BackupRefused
from studyapp.backups.restore import restore_backup

from ._study import InputError


class Command(BaseCommand):
    help = ("Restore a backup folder (from `backup`) into the empty database DATABASE_URL names (created, not "
            "migrated) and into MEDIA_ROOT, CHECKPOINT_ROOT and STUDYAPP_VAR_DIR. Every file is checked against "
            "backup.json first; a non-empty database, a changed file or a file that would be replaced is refused, "
            "restoring nothing. Run `migrate` afterwards when the code is newer than the backup.")

    def add_arguments(self, parser):
        parser.add_argument("folder", type=Path, help="the backup folder")

    def handle(self, *args, **options):
        folder: Path = options["folder"]
        try:
            manifest = restore_backup(folder)
        except (BackupRefused, DatabaseError) as error:
            raise InputError(str(error)) from None
        size = sum(entry.size for entry in manifest.files)
        self.stdout.write(f"the database and {len(manifest.files)} files ({size / 1e6:.1f} MB) of {manifest.created} "
                          f"restored from {folder}")
