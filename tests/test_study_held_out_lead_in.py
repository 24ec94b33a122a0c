"""A study's held-out controls with a lead-in: each clip starts part-way into its take, the
models warm up on the take's control before it, and NAT shows the same frames of the take
(as ``sample -c held-out --lead-in`` and ``natural --lead-in`` do outside a study)."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from django.core.management import call_command

from generation.motion.bvh import load_motion
from generation.motion.npz import load_motion_npz
from generation.control import PathControl
from studyapp.models import ControlSignal, Stimulus, System
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.controls import ControlError, _spread, add_held_out_controls, training_options
from studyapp.stimuli.natural import natural_motion
from studyapp.stimuli.sources import sampled_path
from studyapp.tasks import generate_stimulus
from tests.test_study_researcher import files, new_study, researcher, site, upload_checkpoint  # noqa: F401 (fixtures)

FPS = 20


def path_study(client, researcher, files):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"})
    return study


def post_held_out(client, study, seconds: str, lead_in: str = ""):
    return client.post(f"/studies/{study.pk}/controls/",
                       {"action": "held_out", "seconds": seconds, "count": "", "lead_in": lead_in})


@pytest.mark.django_db
def test_a_lead_in_control_is_its_take_after_the_lead_in_for_the_models_and_for_nat(client, researcher, site, files):
    study = path_study(client, researcher, files)
    assert post_held_out(client, study, "2", lead_in="1").status_code == 302
    led = list(study.controls.filter(origin="held-out").order_by("name"))
    assert led and all(c.name.endswith("-1s+2s") and c.lead_in_seconds == 1.0 for c in led)
    assert "<td>1.00</td>" in client.get(f"/studies/{study.pk}/controls/").content.decode()  # the From (s) column
    post_held_out(client, study, "3")
    options = training_options(study)
    for control in led:  # the same take cut from its start, 3 s long: the lead-in and the clip, in order
        plain = study.controls.get(source_clip=control.source_clip, name__endswith="-3s")
        assert plain.lead_in_seconds == 0.0
        take = np.array(plain.control["velocities"])
        np.testing.assert_array_equal(np.array(control.control["lead_in"]), take[:FPS])
        np.testing.assert_array_equal(np.array(control.control["velocities"]), take[FPS:3 * FPS])
        np.testing.assert_array_equal(natural_motion(control, options).positions,
                                      natural_motion(plain, options).positions[FPS:3 * FPS])

    plan_stimuli(study)
    for stimulus in Stimulus.objects.filter(control__in=led):  # sampled and rendered like any other control
        Stimulus.objects.filter(pk=stimulus.pk).update(task_id=f"led-{stimulus.pk}")  # as if sent to a worker
        assert generate_stimulus.apply((stimulus.pk,), task_id=f"led-{stimulus.pk}").get()["status"] == "done"
    sampled = Stimulus.objects.get(control=led[0], system__role="model")
    assert load_motion_npz(sampled_path(sampled)).n_frames == 2 * FPS
    keys = dict(Stimulus.objects.filter(system__role="natural").values_list("control__name", "content_key"))
    assert len(set(keys.values())) == len(keys)  # NAT of the same take with and without a lead-in: two clips


@pytest.mark.django_db
def test_a_lead_in_longer_than_every_held_out_take_is_refused_and_adds_nothing(client, researcher, site, files):
    study = path_study(client, researcher, files)
    response = post_held_out(client, study, "2", lead_in="59")
    assert response.status_code == 400
    assert "is longer than the lead-in of 59 s" in response.content.decode()
    assert not study.controls.exists()


@pytest.mark.django_db
def test_a_label_controlled_study_is_offered_no_lead_in_and_refuses_one(client, researcher, site, files, settings):
    settings.MOTION_DATA = files.labelled
    study = new_study(researcher)
    upload_checkpoint(client, study, files.erd.read_bytes(), name="ERD")
    assert System.objects.filter(study=study, kind="erd").exists()
    page = client.get(f"/studies/{study.pk}/controls/").content.decode()
    assert 'name="seconds"' in page and 'name="lead_in"' not in page
    with pytest.raises(ControlError, match="a lead-in is the path before the clip"):
        add_held_out_controls(study, 1.0, lead_in=1.0)
    assert not study.controls.exists()


@pytest.mark.django_db
def test_exported_lead_in_controls_carry_their_lead_in_and_natural_clips_of_the_same_frames(
        client, researcher, site, files, tmp_path):
    study = path_study(client, researcher, files)
    said = io.StringIO()
    call_command("add_controls", str(study.pk), "--held-out", "2", "--lead-in", "1", stdout=said)
    assert "-1s+2s" in said.getvalue()
    call_command("export_controls", str(study.pk), "--out", str(tmp_path / "bundle"), "--natural", stdout=io.StringIO())
    index = json.loads((tmp_path / "bundle" / "index.json").read_text())
    assert index["controls"] and all(entry["lead_in_seconds"] == 1.0 for entry in index["controls"])
    options = training_options(study)
    for entry in index["controls"]:
        control = ControlSignal.objects.get(study=study, name=entry["name"])
        arrays = np.load(tmp_path / "bundle" / entry["file"])
        np.testing.assert_array_equal(arrays["lead_in"], np.array(control.control["lead_in"]))
        assert arrays["lead_in"].shape == (FPS, 3) and arrays["velocities"].shape == (entry["frames"], 3)
        natural = load_motion(tmp_path / "bundle" / entry["natural"])
        assert natural.n_frames == natural_motion(control, options).n_frames == entry["frames"]
    assert "lead_in" in (tmp_path / "bundle" / "README.txt").read_text()


def test_a_count_of_held_out_controls_takes_the_clips_that_fill_the_length_first_then_the_longest():
    # A lead-in shortens every clip by its length: a short take would give a clip of a second or two.
    def take(name: str, frames: int) -> PathControl:
        return PathControl(np.zeros((frames, 3)), FPS, name)

    takes = [take("walk-short", 30), take("walk-long", 80), take("walk-full", 80), take("run-short", 20),
             take("run-shorter", 10)]
    contents = {c.name: c.name.split("-")[0] for c in takes}
    names = [c.name for c in _spread(takes, contents, 3)]
    assert names == ["walk-long", "run-short", "walk-full"]
    assert sorted(c.name for c in _spread(takes, contents, None)) == sorted(contents)
