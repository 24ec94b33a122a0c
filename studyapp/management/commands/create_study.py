"""``manage.py create_study OWNER TITLE``: a new study (closed); prints its id.

``manage.py create_study OWNER --from study.yaml`` makes it from a study definition
(``studyapp.definitions``) instead, with its questions, systems and controls.
"""

from pathlib import Path

from django.contrib.auth import get_user_model
from django.core.exceptions import ValidationError
from django.core.management.base import BaseCommand

from studyapp.definitions import DefinitionError, create_study_from_definition
from studyapp.definitions.reading import MAX_DEFINITION_BYTES
from studyapp.designs import registry as designs
from studyapp.models import Study

from ._study import InputError

# The options that set what a definition sets: given with --from, they would be ignored.
SETTINGS = ("design", "scale", "clips", "pages", "ratings_per_stimulus", "training_clips", "platform", "completion_code",
            "size")


def create_study(owner, title: str, **fields) -> Study:
    """A study checked by ``Study.clean`` (as the study form does) and saved."""
    study = Study(owner=owner, title=title, **fields)
    try:
        study.full_clean()
    except ValidationError as error:
        raise InputError("; ".join(f"{k}: {' '.join(v)}" for k, v in error.message_dict.items())) from None
    study.save()
    return study


def read_definition_file(path: Path) -> bytes:
    """The bytes of a definition file (InputError if there is none, or it is too large to be one)."""
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if path.stat().st_size > MAX_DEFINITION_BYTES:
        raise InputError(f"{path}: {path.stat().st_size / 1e6:.1f} MB is over the {MAX_DEFINITION_BYTES / 1e6:g} MB "
                         "a study definition may be")
    try:
        return path.read_bytes()
    except OSError as error:
        raise InputError(f"{path}: cannot read it ({error.strerror or error})") from None


class Command(BaseCommand):
    help = "Create a study owned by a user, from options or from a definition file (--from); the study's id is printed."

    def add_arguments(self, parser):
        parser.add_argument("owner", help="username of the researcher who owns it")
        parser.add_argument("title", nargs="?", help="the study's title (not with --from: the file has it)")
        parser.add_argument("--from", dest="definition", type=Path, metavar="STUDY.yaml",
                            help="a study definition (as describe_study writes): its settings, questions, systems "
                                 "and controls; its checkpoints and submitted motion must be the owner's (uploaded to "
                                 "one of their studies) or shared (SHARED_CHECKPOINTS)")
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
        self.defaults = {name: parser.get_default(name) for name in SETTINGS}

    def handle(self, *args, **options):
        owner = get_user_model().objects.filter(username=options["owner"]).first()
        if owner is None:
            raise InputError(f"no user named {options['owner']!r} (create one with createsuperuser)")
        if options["definition"] is not None:
            study = self.from_definition(owner, options)
        elif options["title"] is None:
            raise InputError("give the study's TITLE, or a definition file with --from")
        else:
            scale = options["scale"] or designs.design_named(options["design"]).default_scale or (1, 5)
            study = create_study(
                owner, options["title"], design=options["design"], scale_min=scale[0], scale_max=scale[1],
                clips_per_participant=options["clips"], pages_per_participant=options["pages"],
                ratings_per_stimulus=options["ratings_per_stimulus"], training_clips=options["training_clips"],
                platform=options["platform"], completion_code=options["completion_code"],
                video_width=options["size"][0], video_height=options["size"][1])
        self.stdout.write(str(study.pk))

    def from_definition(self, owner, options: dict) -> Study:
        given = [name for name in SETTINGS if options[name] != self.defaults[name]]
        if options["title"] is not None or given:
            named = ["TITLE"] * (options["title"] is not None) + [f"--{name.replace('_', '-')}" for name in given]
            raise InputError(f"{', '.join(named)}: the definition file sets these; change them there")
        path = options["definition"]
        try:
            return create_study_from_definition(read_definition_file(path), owner, source=str(path))
        except DefinitionError as error:
            raise InputError(str(error)) from None
