"""``manage.py import_study study.zip --owner USER``: a bundle re-created as a new, closed study."""

from pathlib import Path

from django.contrib.auth import get_user_model
from django.core.management.base import BaseCommand

from studyapp.bundles.importing import import_study
from studyapp.bundles.manifest import BundleRefused

from ._study import InputError


class Command(BaseCommand):
    help = ("Re-create a study from a bundle that export_study wrote: a new study (new key, closed) with its "
            "systems, controls, clips, participants and ratings, all or nothing. A bundle whose files do not "
            "match its manifest, or that is damaged, oversized or of an unknown version, is refused whole. "
            "With --rerun, the same study for new participants, the bundle's ratings kept as its previous run.")

    def add_arguments(self, parser):
        parser.add_argument("bundle", type=Path)
        parser.add_argument("--owner", help="username of the researcher who will own it (default: the one "
                                            "superuser, where there is exactly one)")
        parser.add_argument("--rerun", action="store_true",
                            help="import the design, systems, controls and clips but not the participants: a new "
                                 "run whose report compares its ratings with the bundle's")

    def handle(self, *args, **options):
        users = get_user_model().objects
        if options["owner"] is None:
            superusers = list(users.filter(is_superuser=True)[:2])
            if len(superusers) != 1:
                raise InputError("give --owner USER: the study's owner (there is no one superuser to default to)")
            owner = superusers[0]
        else:
            owner = users.filter(username=options["owner"]).first()
        if owner is None:
            raise InputError(f"no user named {options['owner']!r} (create one with createsuperuser)")
        path: Path = options["bundle"]
        if not path.is_file():
            raise InputError(f"{path}: no such file")
        try:
            study = import_study(str(path), owner, rerun=options["rerun"])
        except BundleRefused as error:
            raise InputError(f"{path}: {error}") from None
        pending = study.stimuli.exclude(status="done").count()
        if pending:
            self.stdout.write(f"{pending} clip(s) to render: manage.py generate_stimuli {study.pk} --wait")
        self.stdout.write(str(study.pk))
