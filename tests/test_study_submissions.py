"""Submitted motion as a system: another lab's clips for the exported controls, checked
before anything is stored, then rendered by the workers like sampled motion.

The "other lab" here uses the exported natural clips (BVH) for the held-out controls and a
tiny MoGlow trained on the real data, sampled outside the study, for the synthetic ones
(``.npz``).
"""

from __future__ import annotations

import html
import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from django.core.files.uploadedfile import SimpleUploadedFile
from django.core.management import call_command
from django.core.management.base import CommandError

from generation.control import control_from_dict
from generation.generator import Generator
from generation.motion.bvh import bvh_text, load_motion, motion_to_bvh
from generation.motion.npz import load_motion_npz, save_motion_npz
from generation.motion.types import Motion, Skeleton
from studyapp.models import Stimulus, Study, System
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.control_export import control_id
from studyapp.stimuli.dispatch import queue_stimuli
from tests.test_study_researcher import (files, new_study, queue, researcher, run_task, site,  # noqa: F401 (fixtures)
                                         upload_checkpoint)

PRESETS = ["walk-straight", "walk-circle", "sidestep-left", "stand-still", "walk-backward", "speed-ramp"]


def study_for_submissions(client, researcher, files) -> Study:
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""})
    client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": PRESETS})
    return study


def other_labs_motion(study: Study, files, tmp_path: Path) -> dict[str, bytes]:
    """A valid submission: file name -> bytes."""
    bundle = tmp_path / "bundle"
    call_command("export_controls", str(study.pk), "--out", str(bundle), "--natural", stdout=io.StringIO())
    generator = Generator.load(files.good)
    submission = {}
    for control in study.controls.all():
        ident = control_id(control)
        if control.origin == "held-out":
            submission[f"lab/{ident}.bvh"] = (bundle / "natural" / f"{ident}.bvh").read_bytes()
        else:
            motion = generator.sample(control_from_dict(control.control), n=1, seed=3)[0]
            submission[f"lab/{ident}.npz"] = save_motion_npz(motion, tmp_path / f"{ident}.npz").read_bytes()
    return submission


def zipped(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def upload_motion(client, study: Study, data: bytes, name: str = "OtherLab"):
    return client.post(f"/studies/{study.pk}/systems/", {
        "action": "motion", "name": name, "role": "model", "motion": SimpleUploadedFile("motion.zip", data)})


def npz_arrays(positions: np.ndarray, like: Motion, fps: float | None = None) -> bytes:
    """The documented .npz layout without offsets (they are optional)."""
    buffer = io.BytesIO()
    np.savez(buffer, positions=positions, fps=np.float64(fps or like.fps), names=np.array(like.skeleton.names),
             parents=like.skeleton.parents)
    return buffer.getvalue()


def npz_bytes(motion: Motion) -> bytes:
    return npz_arrays(motion.positions, motion)


@pytest.mark.django_db
def test_submitted_motion_becomes_a_system_whose_clips_the_workers_render_like_sampled_ones(
        client, researcher, site, files, queue, tmp_path):
    study = study_for_submissions(client, researcher, files)
    submission = other_labs_motion(study, files, tmp_path)
    response = upload_motion(client, study, zipped(submission))
    assert response.status_code == 302, response.content.decode()[-2000:]
    system = System.objects.get(name="OtherLab")
    assert (system.role, system.kind) == ("model", "submitted")
    assert sorted(system.metadata["controls"]) == sorted(study.controls.values_list("name", flat=True))

    stimuli, _ = plan_stimuli(study)
    submitted = [s for s in stimuli if s.system == system]
    assert len(submitted) == study.controls.count()
    queue_stimuli(submitted)
    for stimulus in submitted[:2]:  # one held-out (BVH) and one synthetic (npz) control: controls sort by origin
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
        stimulus.refresh_from_db()
        assert stimulus.duration_s == pytest.approx(stimulus.control.seconds) and stimulus.video_path().is_file()
    moglow = [s for s in stimuli if s.system.name == "MoGlow"]
    assert {s.control_id for s in moglow} == {s.control_id for s in submitted}

    # The same files from a folder on the command line: the motion is stored once, so it is refused as a twin.
    folder = tmp_path / "as-folder"
    for name, data in submission.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)
    with pytest.raises(CommandError, match="already system 'OtherLab'"):
        call_command("add_system", str(study.pk), "Again", "--motion", str(folder), stdout=io.StringIO())


@pytest.mark.django_db
def test_every_control_of_a_refused_submission_is_reported_at_once_and_nothing_is_stored(
        client, researcher, site, files, tmp_path, settings):
    study = study_for_submissions(client, researcher, files)
    good = other_labs_motion(study, files, tmp_path)
    ids = {Path(name).stem: name for name in good}
    held_out = [control_id(c) for c in study.controls.filter(origin="held-out")]
    straight, circle, sidestep, stand, backward, ramp = PRESETS

    def motion_of(ident: str) -> Motion:
        return load_motion_npz(io.BytesIO(good[ids[ident]]))

    bad = dict(good)
    del bad[ids[ramp]]  # missing
    bad["lab/nobody.npz"] = good[ids[straight]]  # unknown
    metres = motion_of(circle)
    bad[ids[circle]] = npz_bytes(Motion(metres.positions / 100, metres.fps, metres.skeleton))
    nan = motion_of(sidestep).positions.copy()
    nan[5, 2, 1] = np.nan
    bad[ids[sidestep]] = npz_arrays(nan, motion_of(sidestep))  # a Motion refuses NaN, so the arrays directly
    short = motion_of(stand)
    bad[ids[stand]] = npz_bytes(Motion(short.positions[:30], short.fps, short.skeleton))
    astray = motion_of(backward)  # drifting 300 cm sideways over the clip: moving its start does not bring it back
    drift = np.linspace(0.0, 300.0, astray.n_frames)[:, None, None] * np.array([1.0, 0.0, 0.0])
    bad[ids[backward]] = npz_bytes(Motion(astray.positions + drift, astray.fps, astray.skeleton))
    slow = motion_of(straight)
    bad[ids[straight]] = npz_bytes(Motion(slow.positions[::2], 10.0, slow.skeleton))
    natural = bvh_motion(good[ids[held_out[0]]], tmp_path)
    fewer = Skeleton(natural.skeleton.names[:-1], natural.skeleton.parents[:-1], natural.skeleton.offsets[:-1])
    bad[ids[held_out[0]]] = bvh_text(motion_to_bvh(Motion(natural.positions[:, :-1], natural.fps, fewer))).encode()

    response = upload_motion(client, study, zipped(bad))
    assert response.status_code == 400
    page = html.unescape(response.content.decode())
    report = page[page.find("the submitted motion was not registered"):][:3000]
    for expected in [
        "motion units: centimetres, y up (unit detected",
        f"{ramp}: no file: refused: no file named {ramp}.bvh or {ramp}_NN.bvh",
        "named after no control, left out: nobody.npz",
        f"{circle}: {circle}.npz: refused: the body is 1.", "cm tall as read; a body is 50-250 cm tall",
        f"{sidestep}: {sidestep}.npz: refused: unreadable ({sidestep}.npz: positions: holds NaN or infinity "
        "(first at frame 5, joint 2))",
        f"{stand}: {stand}.npz: refused: 30 frames (1.50 s) at 20 fps, shorter than its control's 80 frames (4.00 s)",
        f"{backward}: {backward}.npz: refused: the root strays 3", "cm from the control's path (at frame 79); the "
                                                                   "tolerance is 100 cm",
        f"{straight}: {straight}.npz: refused: 10 fps is below the control's 20 fps",
        f"{held_out[0]}: {held_out[0]}.bvh: refused: its skeleton (20 joints) differs from the one of "
        f"{held_out[1]}.bvh (21 joints)",
        f"{held_out[1]}: {held_out[1]}.bvh: read as centimetres, y up; its first 40 of 40 frames (2 s); moved 0.00 m "
        "and turned +0 degrees to start at the origin facing +z; its root at most 2 cm from the path (the tolerance "
        "is 100 cm)",
        "1 of 8 controls ready, 7 refused: nothing written",
    ]:
        assert expected in report, report
    # The refusals in red; what was read and the one control that would be kept, in ink.
    assert f'<li class="accepted">{held_out[1]}: {held_out[1]}.bvh: read as centimetres' in page
    assert '<li class="accepted">motion units: centimetres' in page
    assert f"<li>{straight}: {straight}.npz: refused" in page and "<li>1 of 8 controls ready, 7 refused" in page
    assert not System.objects.filter(name="OtherLab").exists()
    stored = Path(settings.CHECKPOINT_ROOT) / "submitted"
    assert not stored.exists() or not any(stored.iterdir())


def bvh_motion(data: bytes, tmp_path: Path) -> Motion:
    path = tmp_path / "natural.bvh"
    path.write_bytes(data)
    return load_motion(path)


@pytest.mark.django_db
def test_zip_members_never_become_paths_and_a_zip_that_unpacks_past_the_cap_is_refused(
        client, researcher, site, files, tmp_path, settings):
    study = study_for_submissions(client, researcher, files)
    good = other_labs_motion(study, files, tmp_path)
    slipping = {f"../../{Path(name).name}" if i == 0 else name: data for i, (name, data) in enumerate(good.items())}
    first = next(iter(good))
    twice = {**good, f"other/{Path(first).name}": good[first]}  # two files of one name: which is meant?
    response = upload_motion(client, study, zipped(twice), name="Twice")
    assert response.status_code == 400 and (f"{first} and other/{Path(first).name}: only a file&#x27;s name counts, "
                                            "and these have the same") in response.content.decode()
    response = upload_motion(client, study, zipped(slipping))
    assert response.status_code == 302  # the name counts, never the path
    assert not (Path(settings.CHECKPOINT_ROOT).parent / Path(first).name).exists()

    settings.MAX_MOTION_UPLOAD_BYTES = 100_000
    bomb = zipped({"lab/zeros.npz": bytes(5_000_000)})
    assert len(bomb) < 100_000
    response = upload_motion(client, study, bomb, name="Bomb")
    assert response.status_code == 400 and "unpacks to 5 MB, over the 0.1 MB limit" in response.content.decode()
    assert not System.objects.filter(name="Bomb").exists()


@pytest.mark.django_db
def test_videos_may_be_a_model_system_marked_as_not_sharing_the_studys_camera(client, researcher, site, files):
    study = new_study(researcher)
    page = client.get(f"/studies/{study.pk}/systems/").content.decode()
    assert "do not share the study's camera" in page
    response = client.post(f"/studies/{study.pk}/systems/", {
        "action": "videos", "name": "Elsewhere", "role": "model",
        "videos": SimpleUploadedFile("clip.mp4", files.video.read_bytes())})
    assert response.status_code == 302
    system = System.objects.get(name="Elsewhere")
    assert (system.role, system.kind, system.stimuli.get().status) == ("model", "video", "done")
    assert "videos: not the study's camera" in client.get(f"/studies/{study.pk}/systems/").content.decode()
