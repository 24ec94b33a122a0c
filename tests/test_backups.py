"""Backups: ``manage.py backup`` writes the database's snapshot and every file the rows name
with their digests, and ``manage.py restore`` brings a study back, into a database and folders
that never held it, with the same report, file for file, byte for byte; on SQLite here and on
PostgreSQL in the PostgreSQL pass. A restore refuses, writing nothing, a database that is not
empty, a backup whose files differ from its manifest, and a file that would be replaced.

The study is real and small: clips of real motion capture, a real checkpoint, rated by
scripted participants; the restore and the report run in processes of their own, as a
restore onto a new machine does.
"""

from __future__ import annotations

import io
import json
import os
import secrets
import subprocess
import sys
from pathlib import Path
from urllib.parse import quote

import pytest
from django.conf import settings
from django.core.management import CommandError, call_command
from django.db import connection

from generation.checkpoints.store import keep
from studyapp.backups.database import DUMP_NAMES
from studyapp.models import Study, System
from studyapp.researchers.results.reports import create_study_report, report_folder
from tests.conftest import REPO
from tests.study_fixtures import make_study, render_clip_video
from tests.test_report_presentation import rate_everything

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

REPORT_AFTER_RESTORE = """
import sys
import django
django.setup()
from studyapp.models import Study
from studyapp.researchers.results.reports import create_study_report
study = Study.objects.get(pk=int(sys.argv[1]))
print(create_study_report(study, study.owner_id))
"""


@pytest.fixture(scope="module")
def clip_video(motion_data, tmp_path_factory) -> Path:
    bvh = motion_data / "data" / "dataset-1_walk_normal_001.bvh"
    return render_clip_video(bvh, tmp_path_factory.mktemp("video") / "clip.mp4", 1.0)


@pytest.fixture
def deployment(settings, tmp_path) -> Path:
    """This process's folders, apart from the restored deployment's."""
    settings.VAR_DIR = tmp_path / "var"
    settings.MEDIA_ROOT = tmp_path / "var" / "media"
    settings.CHECKPOINT_ROOT = tmp_path / "var" / "checkpoints"
    return tmp_path


def rated_study(clip_video: Path) -> Study:
    """MoGlow, RNN (with a real checkpoint in the store), NAT and BAD on two controls, every clip
    rendered and rated, and the study's report made."""
    study = make_study(controls=2, video=clip_video, bad_checks=0)
    stored, digest = keep(REPO / "models" / "rnn-cpu.safetensors", settings.CHECKPOINT_ROOT)
    System.objects.filter(study=study, name="RNN").update(checkpoint=stored.name, checkpoint_digest=digest)
    means = {"MoGlow": 3, "RNN": 2, "NAT": 4, "BAD": 1}
    rate_everything(study, lambda system, k: max(1, min(5, means[system] + k - 1)))
    return study


def report_files(media_root: Path, digest: str) -> dict[str, bytes]:
    folder = report_folder(media_root, digest)
    return {str(path.relative_to(folder)): path.read_bytes() for path in sorted(folder.rglob("*")) if path.is_file()}


def fresh_database_url(tmp_path: Path) -> str:
    """A new, empty database on this test run's engine (a file for SQLite; a database of its own
    on the test server for PostgreSQL, dropped with the server)."""
    if connection.vendor != "postgresql":
        return f"sqlite:///{tmp_path / 'restored.sqlite3'}"
    name = f"restored_{secrets.token_hex(4)}"
    with connection.cursor() as cursor:
        cursor.execute(f'CREATE DATABASE "{name}"')
    given = connection.settings_dict
    password = f":{quote(given['PASSWORD'], safe='')}" if given.get("PASSWORD") else ""
    return f"postgres://{quote(given['USER'], safe='')}{password}@{given['HOST']}:{given['PORT']}/{name}"


def elsewhere(tmp_path: Path, database_url: str) -> dict[str, str]:
    """The environment of another deployment: its own database and folders."""
    variables = {"DATABASE_URL": database_url, "STUDYAPP_VAR_DIR": str(tmp_path / "restored"),
                 "MEDIA_ROOT": str(tmp_path / "restored" / "media")}
    return {**{k: v for k, v in os.environ.items() if k not in ("CHECKPOINT_ROOT",)}, **variables}


def manage(environment: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "manage.py", *args], cwd=REPO, env=environment, capture_output=True,
                          text=True, timeout=300)


def backup(folder: Path, *args: str) -> str:
    out = io.StringIO()
    call_command("backup", str(folder), *args, stdout=out)
    return out.getvalue()


def test_a_restored_backup_gives_the_same_report_byte_for_byte(deployment, clip_video):
    study = rated_study(clip_video)
    digest = create_study_report(study, study.owner_id)
    original = report_files(deployment / "var" / "media", digest)

    said = backup(deployment / "backup")
    environment = elsewhere(deployment, fresh_database_url(deployment))
    restored = manage(environment, "restore", str(deployment / "backup"))

    assert restored.returncode == 0, restored.stdout + restored.stderr
    manifest = json.loads((deployment / "backup" / "backup.json").read_text())
    assert said.startswith(f"the {manifest['engine']} database and {len(manifest['files'])} files")
    folders = {(entry["folder"], entry["path"].split("/")[0]) for entry in manifest["files"]}
    assert {("media", "stimuli"), ("media", "reports"), ("checkpoints", study.systems.get(name="RNN").checkpoint)
            } <= folders
    again = subprocess.run([sys.executable, "-c", REPORT_AFTER_RESTORE, str(study.pk)], cwd=REPO, env=environment,
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert again.stdout.strip() == digest
    assert report_files(deployment / "restored" / "media", digest) == original
    for stimulus in study.stimuli.all():  # the clips themselves came back too
        assert (deployment / "restored" / "media" / stimulus.relative_path).read_bytes() == clip_video.read_bytes()
    checkpoint = deployment / "restored" / "checkpoints" / study.systems.get(name="RNN").checkpoint
    assert checkpoint.read_bytes() == (REPO / "models" / "rnn-cpu.safetensors").read_bytes()


def test_a_restore_over_a_database_with_tables_is_refused_writing_nothing(deployment, clip_video):
    rated_study(clip_video)
    backup(deployment / "backup")
    environment = elsewhere(deployment, fresh_database_url(deployment))
    assert manage(environment, "migrate", "--noinput").returncode == 0

    refused = manage(environment, "restore", str(deployment / "backup"))

    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "is not empty" in refused.stderr and "restore into a new database that nothing has migrated" in refused.stderr
    assert "Traceback" not in refused.stderr
    assert not (deployment / "restored" / "media" / "stimuli").exists()


def test_a_backup_file_changed_after_the_backup_is_refused_naming_it_and_nothing_is_restored(deployment, clip_video):
    study = rated_study(clip_video)
    backup(deployment / "backup")
    changed = deployment / "backup" / "files" / "media" / study.stimuli.first().relative_path
    changed.write_bytes(changed.read_bytes()[:-1] + b"\0")
    database_url = fresh_database_url(deployment)
    environment = elsewhere(deployment, database_url)

    refused = manage(environment, "restore", str(deployment / "backup"))

    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "1 of the files do not match the backup's manifest, nothing was restored" in refused.stderr
    assert f"{changed}: " in refused.stderr and "not the listed" in refused.stderr
    assert not (deployment / "restored" / "media" / "stimuli").exists()
    # The database is as empty as before: the restore runs once the file is mended.
    changed.write_bytes((deployment / "var" / "media" / study.stimuli.first().relative_path).read_bytes())
    assert manage(environment, "restore", str(deployment / "backup")).returncode == 0


def test_a_restore_that_would_replace_a_different_file_is_refused(deployment, clip_video):
    study = rated_study(clip_video)
    backup(deployment / "backup")
    there = deployment / "restored" / "media" / study.stimuli.first().relative_path
    there.parent.mkdir(parents=True)
    there.write_bytes(b"another deployment's clip")

    refused = manage(elsewhere(deployment, fresh_database_url(deployment)), "restore", str(deployment / "backup"))

    assert refused.returncode == 2 and f"{there}: a different file is there already" in refused.stderr
    assert there.read_bytes() == b"another deployment's clip"


def test_a_backup_that_only_lists_its_files_restores_when_the_folders_are_back(deployment, clip_video):
    study = rated_study(clip_video)
    assert "files" in backup(deployment / "backup", "--list-files-only")
    assert not (deployment / "backup" / "files").exists()
    environment = elsewhere(deployment, fresh_database_url(deployment))

    missing = manage(environment, "restore", str(deployment / "backup"))
    assert missing.returncode == 2 and "missing" in missing.stderr

    # The volumes come back by other means (here a copy), and the restore checks them.
    subprocess.run(["cp", "-a", f"{deployment / 'var'}/.", str(deployment / "restored")], check=True)
    restored = manage(environment, "restore", str(deployment / "backup"))
    assert restored.returncode == 0, restored.stderr
    assert Study.objects.filter(pk=study.pk).exists()


def test_a_backup_names_a_folder_that_is_not_there_yet_outside_the_folders_it_copies(deployment):
    (deployment / "taken").mkdir()
    (deployment / "var" / "media").mkdir(parents=True)
    for folder, message in ((deployment / "taken", "give a folder that does not exist yet"),
                            (deployment / "var" / "media" / "backup", "inside the media folder")):
        with pytest.raises(CommandError) as error:
            backup(folder)
        assert error.value.returncode == 2 and message in str(error.value)
    assert not (deployment / "var" / "media" / "backup").exists()


def test_a_backup_into_a_folder_that_cannot_be_written_is_refused_leaving_nothing(deployment):
    with pytest.raises(CommandError) as error:
        backup(Path("/proc/backup"))  # a system folder nobody may write in, even as root
    assert error.value.returncode == 2 and "no backup written in /proc/backup" in str(error.value)
    assert not any(path.name.startswith(".backup") for path in Path("/proc").iterdir())


@pytest.mark.parametrize(("change", "message"), [
    (lambda record: record.update(engine="oracle"), "unknown engine 'oracle'"),
    (lambda record: record["files"][0].update(path="../../etc/passwd"), "is not a plain path inside its folder"),
    (lambda record: record["files"][0].update(folder="home"), "no folder 'home'"),
    (lambda record: record["files"][0].pop("sha256"), "'sha256' is missing"),
])
def test_a_hostile_or_broken_manifest_is_refused_naming_its_field(deployment, clip_video, change, message):
    rated_study(clip_video)
    backup(deployment / "backup")
    manifest = deployment / "backup" / "backup.json"
    record = json.loads(manifest.read_text())
    change(record)
    manifest.write_text(json.dumps(record))

    refused = manage(elsewhere(deployment, fresh_database_url(deployment)), "restore", str(deployment / "backup"))

    assert refused.returncode == 2 and message in refused.stderr and str(manifest) in refused.stderr
    assert not (deployment / "restored" / "media").exists() or not any((deployment / "restored" / "media").iterdir())


def test_the_dump_is_named_after_its_engine(deployment, clip_video):
    rated_study(clip_video)
    backup(deployment / "backup")
    engine = "postgresql" if connection.vendor == "postgresql" else "sqlite"
    assert (deployment / "backup" / DUMP_NAMES[engine]).is_file()
