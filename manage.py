#!/usr/bin/env python
"""Django's command line for the study app (`python manage.py runserver`, `migrate`, ...)."""

import os
import sys


def main() -> None:
    import studyapp  # noqa: F401 (first: it tunes the garbage collector before Django's imports)

    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.server.settings")
    from django.core.exceptions import ImproperlyConfigured
    from django.core.management import execute_from_command_line
    from django.db import OperationalError, ProgrammingError

    try:
        execute_from_command_line(sys.argv)
    except ImproperlyConfigured as error:  # a setting from the environment that cannot be used: say which
        print(f"manage.py: error: {error}", file=sys.stderr)
        sys.exit(2)
    except (OperationalError, ProgrammingError) as error:  # a database never set up, or out of reach
        print(f"manage.py: error: the database cannot answer ({' '.join(str(error).split())}); "
              "if it was never set up, run: python manage.py migrate", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
