"""The study app's settings with the floor's page added (``benchmarks.stack_floor``)."""

from studyapp.server.settings import *  # noqa: F403

ROOT_URLCONF = "benchmarks.stack_floor"
