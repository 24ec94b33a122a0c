"""The tutorials' commands run as the pages write them, and give what the pages show.

Each test reads its tutorial's ``sh`` blocks and runs their commands (``python`` is this
interpreter, the repository on its path), so a page and its test cannot disagree: a
command that changes, or an output the page names that is no longer written, fails here.
"""

from __future__ import annotations

import io
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TUTORIALS = REPO / "docs" / "tutorials"


def blocks(page: str, language: str) -> list[str]:
    """The fenced blocks of ``language`` in a page, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```", page, flags=re.MULTILINE | re.DOTALL)


def commands(block: str) -> list[str]:
    """A shell block's commands, comments and blank lines left out."""
    lines = [re.split(r"\s{2,}#", line)[0].strip() for line in block.splitlines()]
    return [line for line in lines if line and not line.startswith("#")]


def run(command: str, cwd: Path, timeout: float = 60) -> subprocess.CompletedProcess:
    """One of a page's commands, ``python`` being this interpreter."""
    words = shlex.split(command)
    if words[0] == "python":
        words[0] = sys.executable
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    result = subprocess.run(words, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, f"{command!r} exited with {result.returncode}:\n{result.stderr[-2000:]}"
    return result


def excerpts(page: str) -> dict[str, str]:
    """Each "`FILE`:" or "`FILE` (start):" paragraph's file and the block after it."""
    found = re.findall(r"^`([^`]+)`(?: \(start\))?:\n\n```\w*\n(.*?)^```", page, flags=re.MULTILINE | re.DOTALL)
    return dict(found)


def same_cells(shown: str, written: str) -> bool:
    """One CSV row as the page shows it and as the file has it: text equal, numbers to 1e-6."""
    pairs = list(zip(shown.split(","), written.split(",")))
    if len(shown.split(",")) != len(written.split(",")):
        return False
    for a, b in pairs:
        try:
            if not math.isclose(float(a), float(b), rel_tol=1e-6):
                return False
        except ValueError:
            if a != b:
                return False
    return True


def named_files(page: str) -> list[str]:
    """The report files the table of "What the report folder holds" names, as globs; a name
    without a folder is in the folder of the name before it, and TASK_CLASS stands for any."""
    section = page.split("## What the report folder holds", 1)[1]
    names = []
    for row in re.findall(r"^\| (`.*?) \| ", section, flags=re.MULTILINE):
        if "--motion" in row:  # the objective metrics need motion files: not part of this run
            continue
        folder = ""
        for name in re.findall(r"`([^`]+)`", row):
            folder = name.rpartition("/")[0] + "/" if "/" in name else folder
            names.append(re.sub(r"[A-Z]+(_[A-Z]+)*", "*", folder + name.rpartition("/")[2]))
    return names


@pytest.mark.slow
def test_the_ratings_to_tables_tutorial_writes_every_file_and_excerpt_it_shows(tmp_path):
    page = (TUTORIALS / "ratings-to-tables.md").read_text(encoding="utf-8")
    shell = blocks(page, "sh")
    assert len(shell) == 1
    for command in commands(shell[0]):
        run(command, tmp_path)

    ratings_lines = (tmp_path / "ratings.csv").read_text(encoding="utf-8").splitlines()
    assert blocks(page, "text")[0].splitlines() == ratings_lines[:2], "the ratings table's excerpt"

    names = named_files(page)
    assert "tables/table2_significance.*" in names and "figures/rating_distributions.*" in names
    missing = [name for name in names if not list((tmp_path / "report").glob(name))]
    assert missing == [], "the page names report files the report does not write"
    tables = {path.stem for name in names if name.startswith("tables/")
              for path in (tmp_path / "report").glob(name)}
    not_four_times = sorted(stem for stem in tables if {p.suffix for p in (tmp_path / "report" / "tables").glob(
        f"{stem}.*")} != {".csv", ".md", ".tex", ".json"})
    assert not_four_times == [], "every table is written as .csv, .md, .tex and .json"

    shown = excerpts(page)
    assert set(shown) == {"tables/table2_significance.tex", "tables/exclusions.csv", "tables/anova.csv",
                          "summary.md"}
    for name, excerpt in shown.items():
        written = (tmp_path / "report" / name).read_text(encoding="utf-8")
        if name.endswith(".csv"):
            header, *rows = excerpt.splitlines()
            lines = written.splitlines()
            assert header == lines[0], f"{name}'s header"
            assert all(same_cells(row, line) for row, line in zip(rows, lines[1:])), f"{name}'s rows"
        elif name.endswith(".tex"):
            assert written.startswith(excerpt), f"{name}'s start"
        else:  # sentences wrapped to the page, "..." where the page leaves some out
            flowing = " ".join(written.split())
            pieces = [" ".join(piece.split()) for piece in excerpt.split("...")]
            assert all(piece in flowing for piece in pieces), f"{name}'s sentences"


@pytest.mark.slow
@pytest.mark.django_db
def test_the_own_motion_tutorial_makes_a_study_of_the_submitted_motion(settings, tmp_path, monkeypatch, motion_data,
                                                                       motion_data_2):
    """Its commands in one process, as the page gives them (manage.py's through call_command,
    generation's through its main), YOU and STUDY_ID as the page says to fill them in. The
    last, generate_stimuli --wait, needs a worker: tests/test_study_worker.py runs that."""
    from django.core.management import call_command

    from generation.cli import main as generation_main
    from studyapp.models import Study, System

    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DJANGO_SUPERUSER_PASSWORD", "a password of the test")
    page = (TUTORIALS / "your-model.md").read_text(encoding="utf-8")
    steps = commands(blocks(page, "sh")[0])
    assert steps[-1] == "python manage.py generate_stimuli STUDY_ID --wait"
    study_id = None
    for step in steps[:-1]:
        words = [{"YOU": "you", "STUDY_ID": study_id}.get(word, word) for word in shlex.split(step)]
        if words[:2] == ["python", "manage.py"]:
            if words[2] == "createsuperuser":
                words.append("--noinput")  # the page's account asks for its password
            out = io.StringIO()
            call_command(*words[2:], stdout=out)
            if words[2] == "create_study":
                study_id = out.getvalue().strip()
        elif words[:3] == ["python", "-m", "generation"]:
            assert generation_main(words[3:]) == 0, step
        elif words[:2] == ["cp", "-r"]:
            shutil.copytree(words[2], words[3])
        else:
            pytest.fail(f"the test does not know how to run {step!r}")

    study = Study.objects.get(pk=study_id)
    assert study.owner.username == "you"
    assert [(system.name, system.source_kind) for system in study.systems.order_by("name")] == [
        ("MyLab", System.SourceKind.SUBMITTED), ("NAT", System.SourceKind.NATURAL)]
    assert study.controls.count() == 6
    assert len(list((tmp_path / "controls" / "paths").glob("*.npz"))) == 6


def test_every_variable_the_prolific_tutorial_exports_reaches_the_containers():
    """compose.yaml hands a container only the variables it names: one the page exports
    but compose.yaml leaves out (HTTPS once) would do nothing on the server."""
    page = (TUTORIALS / "prolific.md").read_text(encoding="utf-8")
    compose = (REPO / "compose.yaml").read_text(encoding="utf-8")
    exported = [name for block in blocks(page, "sh") for command in commands(block) if command.startswith("export ")
                for name in re.findall(r"(?:^export |\s)([A-Z][A-Z0-9_]*)=", command)]
    assert {"SECRET_KEY", "MOTION_DATA_DIR", "STUDY_DOMAIN", "ALLOWED_HOSTS", "CSRF_TRUSTED_ORIGINS"} <= set(exported)
    assert [name for name in exported if "${" + name not in compose] == []


@pytest.mark.django_db
def test_the_prolific_tutorials_server_commands_exist_offline(client):
    """What can be followed without a server, Docker or a Prolific account: the secret key's
    command, every manage.py command the page names, and the health page its curl asks."""
    from django.core.management import get_commands

    page = (TUTORIALS / "prolific.md").read_text(encoding="utf-8")
    secret = re.search(r"\$\((python3 -c \"[^\"]*\")\)", page).group(1)
    key = subprocess.run(shlex.split(secret.replace("python3", sys.executable, 1)), capture_output=True, text=True,
                         check=True).stdout.strip()
    assert len(key) >= 50
    named = set(re.findall(r"manage\.py (\w+)", page))
    assert {"create_researcher", "create_study"} <= named and named - set(get_commands()) == set()
    health = re.search(r"curl -s https://study\.example\.org(/\S+)", page).group(1)
    response = client.get(health)
    assert response.status_code == 200 and response.json()["status"] in ("ok", "degraded")


@pytest.mark.slow
@pytest.mark.django_db
def test_the_own_bvh_tutorial_trains_samples_renders_and_adds_a_model(settings, tmp_path, monkeypatch, motion_data_2):
    """Its commands on three walking takes without labels, as the page gives them, but for
    training one step instead of 4,000 and sampling one clip instead of four (a later
    option wins in argparse)."""
    from django.contrib.auth.models import User
    from django.core.management import call_command

    from generation.cli import main as generation_main
    from studyapp.models import System

    takes = tmp_path / "my-bvh"
    takes.mkdir()
    for take in sorted((motion_data_2 / "data").glob("dataset-2_walk_normal_*.bvh"))[:3]:
        shutil.copy(take, takes)
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MOTION_CACHE_DIR", str(tmp_path / "cache"))
    User.objects.create_user("you")
    out = io.StringIO()
    call_command("create_study", "you", "My BVH", stdout=out)
    study_id = out.getvalue().strip()

    page = (TUTORIALS / "your-model.md").read_text(encoding="utf-8")
    block = blocks(page, "sh")[1]
    assert "check-data /path/to/my-bvh          # what it holds; status 1: no committed model applies" in block
    status = {"check-data": 1}
    shorter = {"train": ["--steps", "1", "--eval-every", "1"], "sample": ["--n", "1"]}
    for step in commands(block):
        words = [{"/path/to/my-bvh": str(takes), "STUDY_ID": study_id}.get(word, word) for word in shlex.split(step)]
        if words[:3] == ["python", "-m", "generation"]:
            assert generation_main(words[3:] + shorter.get(words[3], [])) == status.get(words[3], 0), step
        else:
            assert words[:2] == ["python", "manage.py"], step
            call_command(*words[2:], stdout=io.StringIO())

    assert list((tmp_path / "var" / "samples" / "mine").glob("walk-circle_00.mp4"))
    assert System.objects.get(study_id=study_id, name="Mine").kind == "moglow"
