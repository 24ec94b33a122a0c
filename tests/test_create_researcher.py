"""The first researcher of a deployment: ``manage.py create_researcher``."""

import io
import os
import subprocess
import sys

import pytest
from django.contrib.auth.models import User
from django.core.management import CommandError, call_command

from tests.conftest import REPO

pytestmark = pytest.mark.django_db
PASSWORD = "a-long-lab-passphrase-7"


def _create(*args: str) -> str:
    out = io.StringIO()
    call_command("create_researcher", *args, stdout=out)
    return out.getvalue()


def test_a_researcher_is_created_from_a_password_file_and_can_log_in(client, tmp_path):
    secret = tmp_path / "password"
    secret.write_text(PASSWORD + "\n")

    said = _create("ada", "--email", "ada@lab.example", "--password-file", str(secret))

    assert "researcher ada created" in said
    user = User.objects.get(username="ada")
    assert user.email == "ada@lab.example" and user.is_staff and not user.is_superuser
    assert user.has_perm("studyapp.change_study")
    assert client.login(username="ada", password=PASSWORD)
    assert client.get("/studies/").status_code == 200


def test_a_researcher_is_created_from_the_environment(monkeypatch):
    monkeypatch.setenv("STUDY_RESEARCHER_PASSWORD", PASSWORD)

    _create("ada", "--email", "ada@lab.example")

    assert User.objects.get(username="ada").check_password(PASSWORD)


def test_creating_a_researcher_twice_exits_2_naming_the_login_and_changes_nothing(monkeypatch):
    monkeypatch.setenv("STUDY_RESEARCHER_PASSWORD", PASSWORD)
    _create("ada", "--email", "ada@lab.example")
    monkeypatch.setenv("STUDY_RESEARCHER_PASSWORD", PASSWORD + "-other")

    with pytest.raises(CommandError) as error:
        _create("ada", "--email", "other@lab.example")

    assert error.value.returncode == 2
    assert "a login named 'ada' exists already" in str(error.value)
    user = User.objects.get(username="ada")
    assert user.email == "ada@lab.example" and user.check_password(PASSWORD)


@pytest.mark.parametrize(("args", "password", "message"), [
    (("ada", "--email", "ada@lab.example"), "short", "the password is refused: This password is too short"),
    (("ada", "--email", "ada@lab.example"), "password1234", "the password is refused: This password is too common"),
    (("ada lovelace", "--email", "ada@lab.example"), PASSWORD, "username 'ada lovelace': Enter a valid username"),
    (("ada", "--email", "not-an-address"), PASSWORD, "--email 'not-an-address': Enter a valid email address"),
])
def test_a_bad_name_address_or_password_is_refused_creating_nothing(monkeypatch, args, password, message):
    monkeypatch.setenv("STUDY_RESEARCHER_PASSWORD", password)

    with pytest.raises(CommandError) as error:
        _create(*args)

    assert error.value.returncode == 2 and message in str(error.value)
    assert not User.objects.exists()


def test_an_unreadable_or_empty_password_file_is_refused(tmp_path):
    empty = tmp_path / "empty"
    empty.write_text("")
    for path, message in ((tmp_path / "missing", "cannot read the password"), (empty, "the password, is empty")):
        with pytest.raises(CommandError) as error:
            _create("ada", "--email", "ada@lab.example", "--password-file", str(path))
        assert error.value.returncode == 2 and message in str(error.value) and str(path) in str(error.value)
    assert not User.objects.exists()


def test_without_a_password_or_a_terminal_the_command_exits_2_in_one_line(tmp_path):
    environment = {**os.environ, "STUDYAPP_VAR_DIR": str(tmp_path), "DATABASE_URL": ""}
    environment.pop("STUDY_RESEARCHER_PASSWORD", None)
    subprocess.run([sys.executable, "manage.py", "migrate", "--noinput"], cwd=REPO, env=environment, check=True,
                   capture_output=True)

    result = subprocess.run([sys.executable, "manage.py", "create_researcher", "ada", "--email", "ada@lab.example"],
                            cwd=REPO, env=environment, stdin=subprocess.DEVNULL, capture_output=True, text=True)

    assert result.returncode == 2, result.stdout + result.stderr
    assert "no password: give --password-file FILE or set STUDY_RESEARCHER_PASSWORD" in result.stderr
    assert "Traceback" not in result.stderr
