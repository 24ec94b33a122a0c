"""``manage.py create_study OWNER TITLE``: a new study (closed); prints its id."""

from django.contrib.auth import get_user_model
from django.core.exceptions import ValidationError
from django.core.management.base import BaseCommand

from studyapp.designs import registry as designs
from studyapp.models import Study

from ._study import InputError


def create_study(owner, title: str, **fields) -> Study:
    """A study checked by ``Study.clean`` (as the study form does) and saved."""
    study = Study(owner=owner, title=title, **fields)
    try:
        study.full_clean()
    except ValidationError as error:
        raise InputError("; ".join(f"{k}: {' '.join(v)}" for k, v in error.message_dict.items())) from None
    study.save()
    return study


class Command(BaseCommand):
    help = "Create a study owned by a user; the study's id is printed."

    def add_arguments(self, parser):
        parser.add_argument("owner", help="username of the researcher who owns it")
        parser.add_argument("title")
        parser.add_argument("--design", choices=list(designs.DESIGNS), default=designs.DEFAULT)
        parser.add_argument("--scale", nargs=2, type=int, metavar=("MIN", "MAX"),
                            help="default 1 5, or the design's own (side-by-side: 0 100)")
        parser.add_argument("--clips", type=int, default=20, help="clips per participant, attention checks included")
        parser.add_argument("--pages", type=int, default=8, help="side-by-side and pairwise: pages per participant")
        parser.add_argument("--ratings-per-stimulus", type=int, default=10)
        parser.add_argument("--training-clips", type=int, default=4)
        parser.add_argument("--platform", choices=Study.Platform.values, default=Study.Platform.LINK)
        parser.add_argument("--completion-code", default="")
        parser.add_argument("--size", nargs=2, type=int, metavar=("WIDTH", "HEIGHT"), default=(640, 480))

    def handle(self, *args, **options):
        owner = get_user_model().objects.filter(username=options["owner"]).first()
        if owner is None:
            raise InputError(f"no user named {options['owner']!r} (create one with createsuperuser)")
        scale = options["scale"] or designs.design_named(options["design"]).default_scale or (1, 5)
        study = create_study(
            owner, options["title"], design=options["design"], scale_min=scale[0], scale_max=scale[1],
            clips_per_participant=options["clips"], pages_per_participant=options["pages"], ratings_per_stimulus=options["ratings_per_stimulus"],
            training_clips=options["training_clips"], platform=options["platform"],
            completion_code=options["completion_code"], video_width=options["size"][0], video_height=options["size"][1])
        self.stdout.write(str(study.pk))
