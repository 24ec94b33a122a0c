"""The Django that the suite runs on is the series pyproject.toml allows, and it allows no
other: an install can only get the version the tests ran on, or a patch release of it."""

import tomllib

import django
from packaging.requirements import Requirement
from packaging.version import Version

from tests.conftest import REPO


def declared(name: str) -> Requirement:
    dependencies = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    return next(requirement for requirement in map(Requirement, dependencies) if requirement.name == name)


def test_the_django_range_is_the_one_feature_series_the_tests_run_on():
    allowed = declared("django").specifier
    running = Version(django.__version__)

    assert running in allowed
    series = f"{running.major}.{running.minor}"
    assert Version(f"{series}.0") in allowed and Version(f"{series}.99") in allowed
    next_feature = f"{running.major}.{running.minor + 1}" if running.minor < 2 else f"{running.major + 1}.0"
    assert Version(next_feature) not in allowed  # a series nobody tested is refused at install
    assert Version(f"{running.major}.{running.minor - 1}" if running.minor else f"{running.major - 1}.2") not in allowed
