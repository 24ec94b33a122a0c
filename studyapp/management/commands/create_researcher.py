"""``manage.py create_researcher USERNAME --email E [--password-file FILE]``: a researcher's
login, the first one of a new deployment included.

The password comes from ``--password-file`` (its first line), else the environment variable
``STUDY_RESEARCHER_PASSWORD``, else a prompt (asked twice) when the command runs in a terminal;
never from the command line, where other users of the machine and the shell's history see it.
"""

import getpass
import sys
from pathlib import Path

from django.contrib.auth.models import User
from django.core.exceptions import ValidationError
from django.core.management.base import BaseCommand
from django.core.validators import validate_email

from studyapp.researchers.accounts import check_researcher_password, create_researcher
from studyapp.server.env import env_str

from ._study import InputError

PASSWORD_VARIABLE = "STUDY_RESEARCHER_PASSWORD"


def _password_from_file(path: Path) -> str:
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: cannot read the password ({error})") from None
    if not lines or not lines[0]:
        raise InputError(f"{path}: the first line, the password, is empty")
    return lines[0]


def _password_from_prompt() -> str:
    if not sys.stdin.isatty():
        raise InputError(f"no password: give --password-file FILE or set {PASSWORD_VARIABLE} "
                         "(no terminal to ask in)")
    password = getpass.getpass("Password: ")
    if getpass.getpass("Password (again): ") != password:
        raise InputError("the two passwords differ; nothing was created")
    return password


class Command(BaseCommand):
    help = ("Create a researcher's login (staff, with the study app's permissions: the admin shows each researcher "
            "their own studies only). Exits with status 2, creating nothing, when the name is taken.")

    def add_arguments(self, parser):
        parser.add_argument("username")
        parser.add_argument("--email", required=True, help="the researcher's e-mail address")
        parser.add_argument("--password-file", type=Path, metavar="FILE",
                            help=f"a file whose first line is the password; without it {PASSWORD_VARIABLE}, "
                                 "else a prompt")

    def handle(self, *args, **options):
        username, email = options["username"], options["email"]
        checks = (("username", username, User.username_validator), ("--email", email, validate_email))
        for field, value, validate in checks:
            try:
                validate(value)
            except ValidationError as error:
                raise InputError(f"{field} {value!r}: {' '.join(error.messages)}") from None
        if User.objects.filter(username=username).exists():
            raise InputError(f"a login named {username!r} exists already; nothing was changed "
                             "(change its password with `manage.py changepassword`)")
        if options["password_file"] is not None:
            password = _password_from_file(options["password_file"])
        else:
            password = env_str("STUDY_RESEARCHER_PASSWORD", "") or _password_from_prompt()
        try:
            check_researcher_password(password, username, email)
        except ValidationError as error:
            raise InputError(f"the password is refused: {' '.join(error.messages)}") from None
        create_researcher(username, email, password)
        self.stdout.write(f"researcher {username} created; log in at /login/")
