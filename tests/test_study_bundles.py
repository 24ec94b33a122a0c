"""A study as one file: ``export_study`` writes a finished study as a bundle, and
``import_study`` re-creates it in a database and folders that never held it, whose clips
render again to the same content keys and videos and whose ratings give the same report,
file for file, byte for byte; on each of the single, side-by-side and pairwise designs.

The studies are real and small: a tiny MoGlow and an early one as BAD, NAT, and another
lab's submitted motion as RNN, on the held-out controls of a few real takes, clips of one
second at 160×120 rendered by the workers' tasks, rated by scripted participants.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import pytest
from django.core.management import call_command

from analysis.cli import main as analysis_main
from studyapp.models import Participant, Rating, Stimulus, Study
from studyapp.preregistration.lock import preregistration
from studyapp.researchers.results.export import ratings_csv, rules_json
from studyapp.stimuli.clips import plan_stimuli
from studyapp.tasks import sample_stimuli
from tests.test_study_researcher import (files, new_study, queue, researcher, run_task, site,  # noqa: F401 (fixtures)
                                         upload_checkpoint)
from tests.test_study_rules import PAIRWISE_RULES, SIDE_BY_SIDE_RULES, SINGLE_RULES, populate
from tests.test_study_submissions import other_labs_motion, upload_motion, zipped

pytestmark = [pytest.mark.django_db, pytest.mark.slow]

DESIGNS = {"single": SINGLE_RULES, "side-by-side": SIDE_BY_SIDE_RULES, "pairwise": PAIRWISE_RULES}


def render_all(client, study: Study) -> None:
    """Queue the study's clips from its stimuli page and run the workers' tasks in this process."""
    assert client.post(f"/studies/{study.pk}/stimuli/", {"seed": "0"}).status_code == 302
    sampled = [s for s in Stimulus.objects.filter(study=study, system__checkpoint__gt="", status="queued")]
    if sampled:
        sample_stimuli.apply(([(s.pk, s.task_id) for s in sampled],)).get()
    for stimulus in Stimulus.objects.filter(study=study, status="queued"):
        assert run_task(stimulus)["status"] == "done"


def finished_study(client, researcher, files, tmp_path: Path, rules: dict) -> Study:
    """MoGlow, RNN (submitted motion), NAT and BAD on the held-out controls, every clip
    rendered, rated by the scripted participants of the rules test."""
    study = new_study(researcher, clips_per_participant=7, ratings_per_stimulus=10, training_clips=0,
                      platform=Study.Platform.PROLIFIC, completion_code="C0MPL3TE", **rules)
    upload_checkpoint(client, study, files.good.read_bytes())
    upload_checkpoint(client, study, files.early.read_bytes(), name="BAD", role="bad")
    client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"})
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "1", "count": ""})
    assert upload_motion(client, study, zipped(other_labs_motion(study, files, tmp_path)), name="RNN").status_code == 302
    render_all(client, study)
    study.is_open = True  # opened as the pages open it: its plan is locked
    study.save()
    populate(study)
    study.ratings_per_stimulus += 1  # a target raised after opening: a deviation from the plan
    study.save()
    return study


def report_files(ratings: bytes, rules: bytes, folder: Path) -> dict[str, bytes]:
    """``python -m analysis report`` on a ratings table and its rules: every file it writes."""
    folder.mkdir(parents=True)
    (folder / "ratings.csv").write_bytes(ratings)
    (folder / "rules.json").write_bytes(rules)
    out = folder / "report"
    assert analysis_main(["report", str(folder / "ratings.csv"), "--rules", str(folder / "rules.json"),
                          "--out", str(out)]) == 0
    return {str(path.relative_to(out)): path.read_bytes() for path in sorted(out.rglob("*")) if path.is_file()}


def videos_by_content(study: Study) -> dict[str, str]:
    return {stimulus.content_key: hashlib.sha256(stimulus.video_path().read_bytes()).hexdigest()
            for stimulus in study.stimuli.all()}


def another_server(settings, tmp_path: Path, files) -> None:
    """Point the media, checkpoint and var folders somewhere new and delete every study:
    what the import makes, it makes from the bundle alone (the motion data is the same)."""
    Participant.objects.all().delete()  # their assignments protect the clips
    Study.objects.all().delete()
    root = tmp_path / "another-server"
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT, settings.VAR_DIR = root / "media", root / "checkpoints", root / "var"
    settings.VAR_DIR.mkdir(parents=True)
    (settings.VAR_DIR / "cache").symlink_to(files.root / "var" / "cache")


@pytest.mark.parametrize("design", DESIGNS)
def test_an_exported_study_imported_elsewhere_renders_the_same_clips_and_gives_the_same_report(
        design, client, researcher, site, files, queue, settings, tmp_path):
    study = finished_study(client, researcher, files, tmp_path, DESIGNS[design])
    original_report = report_files(ratings_csv(study), rules_json(study).encode(), tmp_path / "original")
    original_videos = videos_by_content(study)
    platform_ids = set(study.participants.values_list("platform_id", flat=True))
    old_key = study.key
    plan = preregistration(study)
    assert plan["locked"] and [row["field"] for row in plan["deviations"]] == ["setting.ratings_per_stimulus"]
    bundle = tmp_path / "study.zip"
    call_command("export_study", str(study.pk), "--out", str(bundle), stdout=io.StringIO())

    another_server(settings, tmp_path, files)
    out = io.StringIO()
    call_command("import_study", str(bundle), "--owner", "researcher", stdout=out)
    imported = Study.objects.get()
    assert str(imported.pk) == out.getvalue().split()[-1]
    assert imported.key != old_key and not imported.is_open and imported.design == design
    assert not set(Participant.objects.values_list("platform_id", flat=True)) & platform_ids  # pseudonymous
    assert preregistration(imported) == plan  # the same plan, hash, lock time and deviations

    # Planning again finds every clip by its content key; rendered here, each is the same video.
    assert set(Stimulus.objects.values_list("status", flat=True)) == {"pending"}
    assert plan_stimuli(imported)[1] == 0
    render_all(client, imported)
    assert videos_by_content(imported) == original_videos

    imported_report = report_files(ratings_csv(imported), rules_json(imported).encode(), tmp_path / "imported")
    assert imported_report.keys() == original_report.keys()
    assert any(name.endswith(".svg") for name in imported_report) and any(n.endswith(".png") for n in imported_report)
    for name, data in original_report.items():
        assert imported_report[name] == data, name


def test_a_rerun_adds_a_system_renders_only_its_clips_and_reports_beside_the_previous_ratings(
        client, researcher, site, files, queue, settings, tmp_path):
    from pandas import read_csv

    from tests.test_study_rules import SCORES, take_part

    original = finished_study(client, researcher, files, tmp_path, SINGLE_RULES)
    bundle = tmp_path / "study.zip"
    call_command("export_study", str(original.pk), "--out", str(bundle), "--with-videos", stdout=io.StringIO())
    out = io.StringIO()
    call_command("import_study", str(bundle), "--owner", "researcher", "--rerun", stdout=out)
    rerun = Study.objects.get(pk=int(out.getvalue().split()[-1]))
    assert not rerun.participants.exists() and rerun.previous_runs.get().ratings_csv == ratings_csv(original).decode()
    old = dict(original.stimuli.values_list("content_key", "system__name"))
    assert dict(rerun.stimuli.filter(status="done").values_list("content_key", "system__name")) == old
    assert all(stimulus.video_path().is_file() for stimulus in rerun.stimuli.all())  # under tokens of its own here

    # One more system: generating makes and renders its clips only; the others keep their keys and files.
    upload_checkpoint(client, rerun, files.early.read_bytes(), name="Early")
    assert client.post(f"/studies/{rerun.pk}/stimuli/", {"seed": "0"}).status_code == 302
    queued = Stimulus.objects.filter(study=rerun, status="queued")
    assert {s.system.name for s in queued} == {"Early"} and queued.count() == rerun.controls.count()
    render_all(client, rerun)
    assert rerun.stimuli.exclude(system__name="Early").count() == len(old)

    Study.objects.filter(pk=rerun.pk).update(is_open=True)
    rerun.refresh_from_db()
    for pid, scores in SCORES.items():
        take_part(rerun, f"new-{pid}", {**scores, "Early": 1})
    response = client.post(f"/studies/{rerun.pk}/report/")
    page = client.get(response["Location"]).content.decode()
    assert "This run beside the previous run" in page

    # The table, as the command line writes it from both runs' files, against the kept ratings counted here.
    (tmp_path / "previous.csv").write_bytes(ratings_csv(original))
    (tmp_path / "previous-rules.json").write_text(rules_json(original))
    (tmp_path / "this.csv").write_bytes(ratings_csv(rerun))
    (tmp_path / "this-rules.json").write_text(rules_json(rerun))
    assert analysis_main(["report", str(tmp_path / "this.csv"), "--rules", str(tmp_path / "this-rules.json"),
                          "--previous", str(tmp_path / "previous.csv"), "--previous-rules",
                          str(tmp_path / "previous-rules.json"), "--out", str(tmp_path / "rerun-report")]) == 0
    table = read_csv(tmp_path / "rerun-report" / "tables" / "previous_run.csv").set_index(["system", "run"])
    for study, run in ((original, "previous"), (rerun, "this")):
        kept = Rating.objects.filter(assignment__participant__study=study, assignment__participant__excluded=False,
                                     answered_before_end=False).exclude(assignment__stimulus__system__role="bad")
        for system in {r.assignment.stimulus.system.export_name for r in kept}:
            values = [r.value for r in kept if r.assignment.stimulus.system.export_name == system]
            assert table.loc[(system, run), "ratings"] == len(values)
            assert table.loc[(system, run), "mean"] == pytest.approx(sum(values) / len(values))
    assert ("Early", "previous") not in table.index and table.loc[("Early", "this"), "mean"] == 1
