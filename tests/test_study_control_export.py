"""A study's controls exported as files (``manage.py export_controls`` and the controls page's download)."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from django.contrib.auth.models import User
from django.core.management import call_command
from django.core.management.base import CommandError

from generation.motion.root import integrate
from generation.motion.bvh import load_motion
from generation.motion.root import root_trajectory
from generation.submission import PATH_TOLERANCE_CM
from tests.test_study_researcher import files, new_study, researcher, site, upload_checkpoint  # noqa: F401 (fixtures)


def path_study(client, researcher, files):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""})
    client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle"]})
    return study


@pytest.mark.django_db
def test_export_controls_writes_every_path_with_its_units_and_the_natural_clips_in_the_controls_frame(
        client, researcher, site, files, tmp_path):
    study = path_study(client, researcher, files)
    out = tmp_path / "bundle"
    said = io.StringIO()
    call_command("export_controls", str(study.pk), "--out", str(out), "--natural", stdout=said)
    assert "(natural clips as BVH in centimetres, y up)" in said.getvalue()

    index = json.loads((out / "index.json").read_text())
    assert index["kind"] == "path" and "y up" in index["axes"] and index["units"]["forward"] == "cm/s"
    assert index["units"]["natural"].startswith("BVH lengths (OFFSET, End Site, position channels) in cm, y up")
    assert sorted(c["name"] for c in index["controls"]) == sorted(study.controls.values_list("name", flat=True))
    held_out = [c for c in index["controls"] if c["origin"] == "held-out"]
    assert held_out and all(c["natural"] == f"natural/{c['id']}.bvh" for c in held_out)
    assert all("natural" not in c for c in index["controls"] if c["origin"] == "synthetic")
    for entry in index["controls"]:
        arrays = np.load(out / entry["file"])
        frames = int(arrays["frames"])
        assert frames == entry["frames"] and float(arrays["fps"]) == 20.0
        assert arrays["velocities"].shape == (frames, 3) and arrays["root_path"].shape == (frames, 2)
        np.testing.assert_array_equal(arrays["velocities"][:, 2], arrays["yaw_velocity"])
        np.testing.assert_allclose(arrays["root_path"], integrate(arrays["velocities"], 20.0).xz)
        assert np.abs(arrays["root_path"][0]).max() == 0.0
    for entry in held_out:  # the natural clip walks its control's path from the origin, facing +z
        motion = load_motion(out / entry["natural"])
        assert motion.n_frames == entry["frames"] and motion.fps == pytest.approx(20.0)
        root = root_trajectory(motion).xz
        path = np.load(out / entry["file"])["root_path"]
        assert np.linalg.norm(root - path, axis=1).max() < PATH_TOLERANCE_CM / 10
    readme = (out / "README.txt").read_text()
    assert "centimetres" in readme and f"{PATH_TOLERANCE_CM:g} cm" in readme and "ID.npz" in readme
    assert "are in centimetres with y up: BVH has no field to say so" in readme

    with pytest.raises(CommandError, match="new or empty folder"):  # never mixes two exports
        call_command("export_controls", str(study.pk), "--out", str(out))


@pytest.mark.django_db
def test_label_controls_are_exported_as_json(client, researcher, site, files, settings, tmp_path):
    settings.MOTION_DATA = files.labelled
    study = new_study(researcher)
    upload_checkpoint(client, study, files.erd.read_bytes(), name="ERD")
    client.post(f"/studies/{study.pk}/controls/", {"action": "labels", "actions": ["walk"], "styles": ["happy"],
                                                  "seconds": "1"})
    call_command("export_controls", str(study.pk), "--out", str(tmp_path / "labels"), stdout=io.StringIO())
    index = json.loads((tmp_path / "labels" / "index.json").read_text())
    assert index["kind"] == "labels" and [c["file"] for c in index["controls"]] == ["labels/walk-happy-1s.json"]
    label = json.loads((tmp_path / "labels" / "labels" / "walk-happy-1s.json").read_text())
    assert (label["action"], label["style"], label["frames"], label["fps"]) == ("walk", "happy", 30, 30.0)


@pytest.mark.django_db
def test_the_controls_download_is_the_owners_alone(client, researcher, site, files):
    study = path_study(client, researcher, files)
    assert "Download the controls" in client.get(f"/studies/{study.pk}/controls/").content.decode()
    response = client.get(f"/studies/{study.pk}/controls.zip")
    assert response.status_code == 200 and response["Content-Type"] == "application/zip"
    names = zipfile.ZipFile(io.BytesIO(response.content)).namelist()
    prefix = f"controls-study-{study.pk}/"
    assert {prefix + "index.json", prefix + "README.txt"} <= set(names)
    assert sum(name.startswith(prefix + "paths/") for name in names) == study.controls.count()

    client.force_login(User.objects.create_user("another", password="pw"))
    assert client.get(f"/studies/{study.pk}/controls.zip").status_code == 404
    client.logout()
    response = client.get(f"/studies/{study.pk}/controls.zip")
    assert response.status_code == 302 and "/login" in response["Location"]
