"""The database tests again on PostgreSQL, the database that deployed studies run on.

    python -m tests.postgres_pass [pytest arguments]      # make test's second pass

``make test`` runs the whole suite on SQLite (the embedded default), then this: the tests
of DATABASE_TESTS, on the PostgreSQL server that DATABASE_URL names, or, when it names
none, on a throwaway cluster of their own (``tests.throwaway_postgres``). pytest-django
creates its test database there (``test_`` and the database's name), so a server named by
DATABASE_URL needs a role that may create databases. Arguments go to pytest; test paths
among them run instead of the list (``python -m tests.postgres_pass tests/test_x.py -x``).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.throwaway_postgres import throwaway_postgres

REPO = Path(__file__).resolve().parents[1]

# The modules of the database's work: migrations, assignment and its concurrency, ratings,
# their export and the monitor, the study designs, stimuli claimed by tasks, removal, the
# plan locked at opening and its deviations, the admin's scoping and the hostile inputs of
# the participant's and the researcher's forms and uploads. Their tests that never meet the
# test database are left out (pytest_collection_modifyitems). A new module of database
# tests belongs here too.
DATABASE_TESTS = (
    "tests/test_migrations.py",
    "tests/test_study_concurrency.py",
    "tests/test_study_design_assignment.py",
    "tests/test_study_design_checks.py",
    "tests/test_study_designs.py",
    "tests/test_study_participant.py",
    "tests/test_study_next_page.py",
    "tests/test_study_monitor.py",
    "tests/test_study_researcher.py",
    "tests/test_study_editing.py",
    "tests/test_study_sampled_cleanup.py",
    "tests/test_crowd_pages.py",
    "tests/test_crowd_platform.py",
    "tests/test_crowd_questionnaires.py",
    "tests/test_crowd_researcher.py",
    "tests/test_study_control_export.py",
    "tests/test_study_definition_refusals.py",
    "tests/test_hostile_web.py",
    "tests/test_hostile_checkpoints.py",
    "tests/test_hostile_ratings.py",
    "tests/test_hostile_database_limits.py",
    "tests/test_lost_tasks.py",
    "tests/test_platform_rules.py",
    "tests/test_platform_codes.py",
    "tests/test_platform_api.py",
    "tests/test_platform_id_binding.py",
    "tests/test_platform_misbehaving.py",
    "tests/test_study_natural_folder.py",
    "tests/test_hostile_numbers.py",
    "tests/test_hostile_ids.py",
    "tests/test_hostile_submitted_zips.py",
    "tests/test_stored_data.py",
    "tests/test_study_video_check.py",
    "tests/test_fuzz_web.py",
    "tests/test_researcher_tools.py",
    "tests/test_study_appropriateness.py",
    "tests/test_study_rules.py",
    "tests/test_study_submissions.py",
    "tests/test_study_plan.py",
    "tests/test_study_bundles.py",
    "tests/test_hostile_bundles.py",
    "tests/test_study_bundle_pages.py",
    "tests/test_server_queries.py",
    "tests/test_backups.py",
)


def is_postgres(url: str) -> bool:
    return url.startswith(("postgres://", "postgresql://", "pgsql://"))


def uses_the_database(item: pytest.Item) -> bool:
    """Whether a test meets the test database: marked django_db, or given a fixture that
    needs it (db, transactional_db, live_server, ...)."""
    return item.get_closest_marker("django_db") is not None or "django_db_setup" in item.fixturenames


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """This pass's pytest plugin: a test of the listed modules that never meets the test
    database (a pure function, a subprocess with a database of its own) already ran on
    SQLite and would run the same here, so it is left out."""
    elsewhere = [item for item in items if not uses_the_database(item)]
    if elsewhere:
        config.hook.pytest_deselected(items=elsewhere)
        items[:] = [item for item in items if uses_the_database(item)]


def run_pytest(database_url: str, arguments: list[str]) -> int:
    """pytest in a process of its own, whose settings read ``database_url``."""
    chosen = [a for a in arguments if not a.startswith("-") and (REPO / a.split("::")[0]).exists()]
    tests = [] if chosen else list(DATABASE_TESTS)
    print(f"postgres_pass: {len(chosen or tests)} test module(s) on {database_url}", file=sys.stderr, flush=True)
    return subprocess.call([sys.executable, "-m", "pytest", "-p", "tests.postgres_pass", *tests, *arguments],
                           cwd=REPO, env={**os.environ, "DATABASE_URL": database_url})


def main(arguments: list[str]) -> int:
    named = os.environ.get("DATABASE_URL", "")
    if is_postgres(named):
        return run_pytest(named, arguments)
    with throwaway_postgres(durable=False) as (url, _):
        return run_pytest(url, arguments)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
