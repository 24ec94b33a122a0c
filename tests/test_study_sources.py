"""Every kind of system yields motion through one source interface (``studyapp.stimuli.sources``).

The stimuli and the tasks ask a system's source which controls it has motion for and
what that motion is; no code there branches on a system's role or kind.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile

from studyapp.models import Stimulus, System
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.dispatch import queue_stimuli
from studyapp.stimuli.sources import SOURCES, CheckpointSource, NaturalClips, UploadedVideos, source_of
from studyapp.stimuli.systems import add_video_system
from tests.test_study_researcher import (files, new_study, queue, researcher, run_task, site,  # noqa: F401 (fixtures)
                                         upload_checkpoint)

REPO = Path(__file__).resolve().parents[1]


def comparisons_of_roles_and_kinds(module: Path) -> list[str]:
    """Every comparison (``==``, ``in``, ...) in the module's code that reads a system's role or kind."""
    found = []
    for node in ast.walk(ast.parse(module.read_text())):
        if isinstance(node, (ast.Compare, ast.Match)):
            read = {n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)}
            if read & {"role", "Role", "kind", "source_kind"}:
                found.append(f"{module.name}:{node.lineno}")
    return found


def test_the_stimuli_and_the_tasks_never_branch_on_a_systems_role_or_kind():
    assert comparisons_of_roles_and_kinds(REPO / "studyapp" / "stimuli" / "clips.py") == []
    assert comparisons_of_roles_and_kinds(REPO / "studyapp" / "tasks.py") == []


def test_every_source_kind_has_a_source():
    assert set(SOURCES) == set(System.SourceKind.values)


@pytest.mark.django_db
def test_each_system_plans_the_controls_its_source_has_motion_for(client, researcher, site, files, queue):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"})
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "1", "count": ""})
    client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle"]})
    videos = add_video_system(study, "BAD", [SimpleUploadedFile("bad.mp4", files.video.read_bytes())])
    systems = {s.name: s for s in study.systems.all()}
    assert {name: type(source_of(s)) for name, s in systems.items()} == {
        "MoGlow": CheckpointSource, "NAT": NaturalClips, "BAD": UploadedVideos}

    stimuli, created = plan_stimuli(study)
    held_out = study.controls.filter(origin="held-out").count()
    planned = {name: sorted(s.control.name for s in stimuli if s.system.name == name) for name in systems}
    assert planned["MoGlow"] == sorted(study.controls.values_list("name", flat=True))
    assert planned["NAT"] == sorted(study.controls.filter(origin="held-out").values_list("name", flat=True))
    assert planned["BAD"] == [] and created == held_out + 1 + held_out
    assert Stimulus.objects.filter(system=videos).count() == 1  # the upload's own finished stimulus

    # Both rendered sources go through the one render path to a finished clip of the control's length.
    for stimulus in (stimuli[0], next(s for s in stimuli if s.system.name == "NAT")):
        stimulus.refresh_from_db()
        queue_stimuli([stimulus])
        assert run_task(stimulus)["status"] == "done"
        stimulus.refresh_from_db()
        assert stimulus.duration_s == pytest.approx(stimulus.control.seconds) and stimulus.video_path().is_file()
