"""Submissions from raw BVH: a lab's files in their own unit and up axis, starting anywhere,
become what the study's submitted-motion upload accepts, the same motion whatever unit
they came in, with a report per control of what was matched, converted and refused."""

from __future__ import annotations

import html
import io
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from generation.cli import main
from generation.control import preset_path, take_paths
from generation.motion.bvh import load_motion, motion_to_bvh, write_bvh
from generation.motion.rotations import matrix_to_quat, quat_to_matrix, yaw_matrix
from generation.motion.takes import natural_takes
from generation.motion.types import Motion
from generation.submission import match_files, prepare_submission
from studyapp.stimuli.control_export import bundle_zip, control_id, natural_in_control_frame
from studyapp.stimuli.controls import training_options
from studyapp.stimuli.natural import natural_clip, natural_motion
from studyapp.models import Stimulus, System
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.dispatch import queue_stimuli
from studyapp.stimuli.submissions import check_submission, read_zip
from tests.rig_variants import in_unit, z_up
from tests.test_render import decode
from tests.test_study_researcher import (files, new_study, queue, researcher, run_task, site,  # noqa: F401 (fixtures)
                                         upload_checkpoint)
from tests.test_study_submissions import upload_motion


def placed_elsewhere(motion: Motion, turn_degrees: float, shift_cm: tuple[float, float]) -> Motion:
    """The motion turned about the vertical and moved along the floor: a take captured
    somewhere else in the room, facing another way."""
    turning = yaw_matrix(np.radians(turn_degrees))
    shift = np.array([shift_cm[0], 0.0, shift_cm[1]])
    rotations, translations = motion.rotations.copy(), motion.translations.copy()
    rotations[:, 0] = matrix_to_quat(turning @ quat_to_matrix(rotations[:, 0]))
    translations[:, 0] = translations[:, 0] @ turning.T + shift
    return Motion(motion.positions @ turning.T + shift, motion.fps, motion.skeleton, rotations, translations)


def test_files_are_matched_by_control_id_or_as_sample_numbers_its_clips(tmp_path):
    names = ["walk.bvh", "walk_01.bvh", "circle_02.bvh", "circle-1.bvh", "circle_10.bvh", "stand_01.bvh",
             "stand_01_03.bvh", "notes.bvh"]
    files = [tmp_path / name for name in names]
    matched, unmatched = match_files(files, ["walk", "circle", "stand_01", "ramp"])
    assert {ident: [p.name for p in paths] for ident, paths in matched.items()} == {
        "walk": ["walk.bvh", "walk_01.bvh"], "circle": ["circle-1.bvh", "circle_02.bvh", "circle_10.bvh"],
        "stand_01": ["stand_01.bvh", "stand_01_03.bvh"], "ramp": []}
    assert [p.name for p in unmatched] == ["notes.bvh"]


@pytest.fixture(scope="module")
def cmu(lab_rigs) -> Path:
    """A real walk on CMU's rig, in CMU units (``tests/lab_rigs.py``)."""
    return lab_rigs["cmu"] / "take_01.bvh"


@pytest.fixture(scope="module")
def cmu_control(cmu):
    """A path the CMU take itself follows for 3 s, as a study's held-out control would be."""
    (take,), _ = natural_takes(cmu.parent, names=[cmu.stem])
    return take_paths([("walk", take.control)], 20.0, 3.0)[0]


def test_a_take_in_cmu_units_and_in_metres_is_submitted_as_the_same_clip_at_the_controls_start(
        cmu, cmu_control, lab_rigs, tmp_path):
    clips = {}
    for unit, source in (("cmu", cmu), ("metres", lab_rigs["cmu-metres"] / cmu.name)):
        folder = tmp_path / unit
        folder.mkdir()
        shutil.copy(source, folder / "walk_00.bvh")
        report = prepare_submission([folder / "walk_00.bvh"], {"walk": cmu_control})
        assert report.accepted, report.lines()
        clips[unit] = report.results[0].motion
    # The two files differ by their rounding only: 0.0001 cm (tests/lab_rigs.py).
    np.testing.assert_allclose(clips["cmu"].positions, clips["metres"].positions, atol=0.005)
    moved = clips["cmu"]
    original = load_motion(cmu, 2.54 / 0.45).positions[::6][:60]  # 120 fps to 20: every sixth frame
    for t in (0, 30, 59):  # a rigid motion on the floor: the same body, the same heights
        np.testing.assert_allclose(np.linalg.norm(moved.positions[t] - moved.positions[t, 0], axis=-1),
                                   np.linalg.norm(original[t] - original[t, 0], axis=-1), atol=1e-6)
        np.testing.assert_allclose(moved.positions[t, :, 1], original[t, :, 1], atol=1e-6)


def test_every_refusal_is_listed_per_control_and_nothing_is_written(cmu, cmu_control, tmp_path, capsys):
    folder = tmp_path / "lab"
    folder.mkdir()
    shutil.copy(cmu, folder / "walk.bvh")
    text = cmu.read_bytes()
    head, rows = text.split(b"Frame Time: .0083333\n")
    (folder / "short.bvh").write_bytes(head.replace(b"Frames: 510", b"Frames: 200") + b"Frame Time: .0083333\n"
                                       + b"".join(rows.splitlines(keepends=True)[:200]))
    (folder / "broken.bvh").write_bytes(text[: len(text) // 2])
    shutil.copy(cmu, folder / "astray.bvh")
    (folder / "extra.bvh").write_bytes(text)
    controls = {name: cmu_control for name in ("walk", "short", "broken", "missing")}
    controls["astray"] = preset_path("walk-backward")  # the take walks forwards
    bundle = tmp_path / "controls"
    bundle_of(controls, bundle)
    out = tmp_path / "submission.zip"
    assert main(["prepare-submission", str(folder), "--controls", str(bundle), "-o", str(out)]) == 2
    said = capsys.readouterr().out.splitlines()
    assert said[0].startswith("motion units: CMU units (x5.64444 to cm), y up (unit detected")
    assert said[1].startswith("walk: walk.bvh: read as CMU units (x5.64444 to cm), y up; resampled from 120 to 20 "
                              "fps; its first 60 of 85 frames (3 s); moved 4.68 m and turned +2 degrees to start at "
                              "the origin facing +z; its root at most 5 cm from the path (the tolerance is 100 cm)")
    assert said[2] == ("short: short.bvh: refused: 34 frames (1.70 s) at 20 fps, shorter than its control's 60 "
                       "frames (3.00 s)")
    assert said[3].startswith(f"broken: broken.bvh: refused: unreadable ({folder / 'broken.bvh'}:")
    assert said[4] == "missing: no file: refused: no file named missing.bvh or missing_NN.bvh"
    assert said[5].startswith("astray: astray.bvh: refused: the root strays 907 cm") and "tolerance is 100 cm" in said[5]
    assert said[6:] == ["named after no control, left out: extra.bvh", "1 of 5 controls ready, 4 refused: nothing written"]
    assert not out.exists()
    # Left where it was captured, the walk does not start where its control does.
    assert main(["prepare-submission", str(folder), "--controls", str(bundle), "-o", str(out), "--keep-root"]) == 2
    assert "walk: walk.bvh: refused: the root strays 4" in capsys.readouterr().out and not out.exists()  # 4.68 m away



def test_a_wider_path_tolerance_accepts_motion_that_need_not_follow_its_control(cmu, cmu_control, tmp_path, capsys):
    folder = tmp_path / "lab"
    folder.mkdir()
    shutil.copy(cmu, folder / "walk.bvh")
    bundle = tmp_path / "controls"
    bundle_of({"walk": cmu_control}, bundle)
    out = tmp_path / "submission.zip"
    command = ["prepare-submission", str(folder), "--controls", str(bundle), "-o", str(out), "--keep-root"]
    assert main(command) == 2 and not out.exists()  # left where it was captured, 4.68 m from the path's start
    assert "the tolerance is 100 cm" in capsys.readouterr().out
    assert main([*command, "--path-tolerance", "600"]) == 0 and out.is_file()
    assert "(the tolerance is 600 cm)" in capsys.readouterr().out


@pytest.mark.parametrize("tolerance", ["0", "-5", "nan", "inf", "wide"])
def test_a_path_tolerance_that_is_not_positive_finite_centimetres_is_refused(tolerance, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["prepare-submission", str(tmp_path), "--controls", str(tmp_path), "-o", str(tmp_path / "s.zip"),
              "--path-tolerance", tolerance])
    assert exit_.value.code == 2
    error = capsys.readouterr().err
    assert "--path-tolerance" in error and f"positive number of centimetres, got {tolerance!r}" in error


def bundle_of(controls, folder):
    """A controls bundle as the study exports it (studyapp.stimuli.control_export), for tests without a study."""
    (folder / "paths").mkdir(parents=True)
    entries = []
    for ident, control in controls.items():
        np.savez(folder / "paths" / f"{ident}.npz", velocities=control.velocities, fps=np.float64(control.fps))
        entries.append({"id": ident, "name": ident, "file": f"paths/{ident}.npz"})
    (folder / "index.json").write_text(json.dumps({"controls": entries}))


def as_a_lab_has_them(controls, tmp_path) -> tuple[Path, Path]:
    """Two folders of the held-out controls' real takes: as captured (centimetres, y up,
    30 fps, named by control id), and as another lab's tools would write them: turned and
    moved elsewhere on the floor, in metres with z up, named as ``sample`` names clips,
    with a second clip of one control."""
    centimetres, raw = tmp_path / "as-captured", tmp_path / "lab"
    centimetres.mkdir(), raw.mkdir()
    for turn, control in zip((140.0, -75.0), controls):
        take = natural_clip(control.source_clip)
        shutil.copy(take, centimetres / f"{control_id(control)}.bvh")
        elsewhere = placed_elsewhere(load_motion(take), turn, (350.0, -420.0))
        write_bvh(in_unit(motion_to_bvh(z_up(elsewhere), "XYZ"), 100.0), raw / f"{control_id(control)}_00.bvh")
    shutil.copy(raw / f"{control_id(controls[0])}_00.bvh", raw / f"{control_id(controls[0])}_01.bvh")
    return centimetres, raw


def zip_of(folder: Path) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for path in sorted(folder.iterdir()):
            archive.write(path, f"{folder.name}/{path.name}")
    return buffer.getvalue()


def held_out_study(client, researcher, files):  # noqa: F811
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""})
    assert study.controls.count() == 2
    return study


@pytest.mark.django_db
def test_prepare_submission_makes_a_raw_bvh_folder_into_the_same_motion_as_in_centimetres(
        client, researcher, site, files, tmp_path, capsys):  # noqa: F811
    study = held_out_study(client, researcher, files)
    controls = list(study.controls.all())
    bundle = tmp_path / "controls.zip"
    bundle.write_bytes(bundle_zip(study))
    centimetres, raw = as_a_lab_has_them(controls, tmp_path)

    submitted = {}
    for folder in (centimetres, raw):
        out = tmp_path / f"{folder.name}.zip"
        assert main(["prepare-submission", str(folder), "--controls", str(bundle), "-o", str(out)]) == 0
        with out.open("rb") as stream:
            accepted, _ = check_submission(study, read_zip(stream))
        submitted[folder.name] = {a.control.pk: a.motion for a in accepted}
    said = capsys.readouterr().out
    assert "motion units: metres (x100 to cm), z up (unit detected" in said
    assert f"{control_id(controls[0])}_00.bvh (left out: {control_id(controls[0])}_01.bvh): read as metres" in said

    options = training_options(study)
    for control in controls:
        from_raw, from_centimetres = submitted["lab"][control.pk], submitted["as-captured"][control.pk]
        np.testing.assert_allclose(from_raw.positions, from_centimetres.positions, atol=1e-3)
        # What the study itself places at the control's start: its natural clip, moved by its own code.
        expected = natural_in_control_frame(natural_motion(control, options), options.root)
        np.testing.assert_allclose(from_raw.positions, expected.positions, atol=1e-3)
    with zipfile.ZipFile(tmp_path / "lab.zip") as archive:
        assert sorted(archive.namelist()) == sorted(f"{control_id(c)}.bvh" for c in controls)


@pytest.mark.django_db
def test_a_raw_bvh_submission_in_metres_z_up_starting_anywhere_is_accepted_on_the_page_and_renders_like_centimetres(
        client, researcher, site, files, queue, tmp_path):  # noqa: F811
    study = held_out_study(client, researcher, files)
    controls = list(study.controls.all())
    centimetres, raw = as_a_lab_has_them(controls, tmp_path)
    for name, folder in (("Centimetres", centimetres), ("Metres", raw)):
        response = upload_motion(client, study, zip_of(folder), name)
        assert response.status_code == 302, html.unescape(response.content.decode())[-3000:]
    metres = System.objects.get(name="Metres")
    page = html.unescape(client.get(f"/studies/{study.pk}/systems/").content.decode())
    first = control_id(controls[0])
    for line in metres.metadata["report"]:  # the report of what became of each file, on the systems page
        assert line in page
    assert metres.metadata["report"][0].startswith("motion units: metres (x100 to cm), z up (unit detected")
    assert metres.metadata["report"][1].startswith(f"{first}: {first}_00.bvh (left out: {first}_01.bvh): read as "
                                                   "metres (x100 to cm), z up; resampled from 30 to 20 fps")

    stimuli, _ = plan_stimuli(study)
    submitted = [s for s in stimuli if s.system.kind == "submitted"]
    queue_stimuli(submitted)
    for stimulus in submitted:
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
    for control in controls:
        videos = [decode(Stimulus.objects.get(system__name=name, control=control).video_path())
                  for name in ("Centimetres", "Metres")]
        assert videos[0].shape == videos[1].shape == (40, 120, 160, 3)
        # The same pictures: at most a pixel's edge differs where the files' rounding moves a bone.
        differing = np.abs(videos[0].astype(int) - videos[1].astype(int)).max(axis=-1) > 24
        assert differing.mean() < 0.002, differing.mean()
        assert videos[0].std() > 10  # a figure was drawn, not a blank frame
