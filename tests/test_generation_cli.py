"""The generation command line on real clips and on malformed input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from generation.cli import main
from generation.gallery import GalleryOptions, build_gallery, choose_clips
from generation.motion.bvh import bvh_duration


def test_info_describes_a_real_clip(clip_path, capsys):
    assert main(["info", str(clip_path("walk_normal_001"))]) == 0
    out = capsys.readouterr().out
    assert "195 frames at 30 fps" in out and "Toes_R" in out


def test_render_writes_a_video_and_sheet(clip_path, tmp_path):
    target = tmp_path / "clips" / "walk.mp4"
    assert main(["render", str(clip_path("walk_normal_001")), "-o", str(target), "--sheet", "--size", "320x240"]) == 0
    assert target.stat().st_size > 10_000 and target.with_suffix(".png").is_file()


def test_render_draws_a_control_under_a_take_cut_to_its_length_and_refuses_a_longer_control(clip_path, tmp_path,
                                                                                           capsys):
    from PIL import Image

    from generation.render import Style

    target = tmp_path / "walk.mp4"
    assert main(["render", str(clip_path("walk_normal_001")), "-o", str(target), "--sheet", "--size", "320x240",
                 "--draw-control", "walk-circle"]) == 0
    sheet = np.asarray(Image.open(target.with_suffix(".png")).convert("RGB")).astype(int)
    for colour in (Style().control_past, Style().control_future):
        assert (np.abs(sheet - np.array(colour)).sum(axis=-1) < 20).sum() > 100  # the circle is drawn
    long_walk = tmp_path / "long.yaml"
    long_walk.write_text("segments:\n  - {type: straight, speed: 100, seconds: 10}\n")
    assert main(["render", str(clip_path("walk_normal_001")), "-o", str(tmp_path / "long.mp4"),
                 "--draw-control", str(long_walk)]) == 2
    assert "walk_normal_001.bvh: the take lasts 130 frames at 20 fps, shorter than the 200 of the control" \
        in capsys.readouterr().err
    assert not (tmp_path / "long.mp4").exists()


def test_malformed_bvh_is_named_with_its_line_and_leaves_no_output(clip_path, tmp_path, capsys):
    lines = clip_path("walk_normal_001").read_text().splitlines()
    lines[200] = lines[200].rstrip().rsplit(" ", 1)[0]  # a frame row one value short
    bad = tmp_path / "bad.bvh"
    bad.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert main(["render", str(bad), "-o", str(out / "bad.mp4")]) == 2
    assert f"{bad}:201: the frame row needs 132 numbers, found 131" in capsys.readouterr().err
    assert not out.exists() or list(out.iterdir()) == []


def test_build_dataset_refuses_a_folder_with_a_bad_file_and_caches_nothing(clip_path, tmp_path, capsys):
    folder = tmp_path / "bvh"
    folder.mkdir()
    (folder / "good.bvh").symlink_to(clip_path("walk_normal_001"))
    (folder / "broken.bvh").write_text(clip_path("run_normal_001").read_text()[:-5000])
    cache = tmp_path / "cache"
    assert main(["build-dataset", str(folder), "--cache-dir", str(cache)]) == 2
    assert "broken.bvh" in capsys.readouterr().err
    assert not cache.exists() or list(cache.iterdir()) == []


def test_gallery_renders_clips_and_an_index(motion_data, tmp_path):
    options = GalleryOptions(seconds=1.0, size=(320, 240), contents=("walk", "bow"))
    entries = build_gallery(motion_data, tmp_path, options, progress=False)
    assert [e["content"] for e in entries] == ["bow", "walk"]
    assert all(e["style"] == "normal" for e in entries)  # the plain style is shown first
    index = json.loads((tmp_path / "index.json").read_text())
    assert index == entries
    for entry in entries:
        assert (tmp_path / entry["file"]).stat().st_size > 1000
        assert (tmp_path / entry["sheet"]).is_file()
        assert Image.open(tmp_path / entry["poster"]).size == (320, 240)  # the video's first frame, at its size
        assert entry["frames"] == 20 and entry["fps"] == 20.0
    # Rendering again reuses the files.
    before = {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("*.mp4")}
    build_gallery(motion_data, tmp_path, options, progress=False)
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("*.mp4")} == before
    assert np.isfinite([e["frames"] for e in entries]).all()


def test_the_gallery_leaves_out_clips_shorter_than_a_second(motion_data):
    # Dataset 1's normal dash lasts 0.67 s and its normal run 0.8 s.
    every = choose_clips(motion_data, 100, ("dash", "run"), seconds=4.0)
    assert {"dataset-1_dash_normal_001.bvh", "dataset-1_run_normal_001.bvh"} <= {path.name for path in every}
    shown = choose_clips(motion_data, 100, ("dash", "run"), seconds=4.0, min_seconds=GalleryOptions().min_seconds)
    assert shown == [path for path in every if bvh_duration(path) >= 1.0] and len(shown) == len(every) - 2
    # One a content: the longest take where none lasts the clip's 4 s.
    dash = choose_clips(motion_data, 1, ("dash",), seconds=4.0, min_seconds=1.0)
    assert bvh_duration(dash[0]) == max(bvh_duration(path) for path in every if "_dash_" in path.name)


def test_natural_clips_export_feeds_the_objective_metrics(motion_data, tmp_path, capsys):
    from analysis.cli import main as analysis_main

    out = tmp_path / "motion" / "NAT"
    assert main(["natural", str(motion_data), "--contents", "walk", "--out", str(out)]) == 0
    clips = sorted(out.glob("*.npz"))
    assert clips and all(np.load(c)["positions"].shape == (80, 21, 3) for c in clips)
    capsys.readouterr()
    assert analysis_main(["objective", str(tmp_path / "motion"), "--out", str(tmp_path / "objective")]) == 0
    table = (tmp_path / "objective" / "tables" / "objective_metrics.csv").read_text()
    assert table.startswith("system,n_clips,v_tol_95,steps_per_s")
    assert "NAT" in table and (tmp_path / "objective" / "figures" / "footstep_curves.png").is_file()
    # each take carries its own control, placed where it starts: it follows it all but exactly
    adherence = pd.read_csv(tmp_path / "objective" / "tables" / "control_adherence.csv").iloc[0]
    assert adherence["n_clips"] == len(clips)
    assert adherence["position_error_mean"] < 1.0 and adherence["heading_error_mean"] < 1.0


def test_commands_read_other_units_and_up_axes_and_say_which(clip_path, tmp_path, capsys):
    from tests.rig_variants import write_variants

    variants = write_variants(clip_path("walk_normal_001"), tmp_path / "rigs")
    odd = variants["cmu, z-up, inches"]
    assert main(["render", str(odd), "-o", str(tmp_path / "odd.mp4"), "--size", "160x120"]) == 0
    assert "motion units: inches (x2.54 to cm), z up (unit detected" in capsys.readouterr().out
    assert main(["info", str(odd), "--scale", "in", "--up", "z"]) == 0
    assert "motion units: inches (x2.54 to cm), z up (scale given; up axis given)" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_:
        main(["render", str(odd), "-o", str(tmp_path / "x.mp4"), "--scale", "furlongs"])
    assert exit_.value.code == 2 and "scale must be auto, a unit" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["info", "build-dataset", "render", "gallery", "train", "natural",
                                     "hvrnn-classifiers", "hvrnn-denoiser", "hvrnn-eval", "hvrnn-label"])
def test_every_command_that_reads_bvh_takes_the_unit_and_up_axis(command, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([command, "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "--scale auto|UNIT|NUMBER" in out and "--up {auto,y,z}" in out and "(default auto)" in out


def test_build_dataset_refuses_mixed_units_naming_the_outliers(clip_path, tmp_path, capsys):
    from tests.rig_variants import write_variants

    folder = tmp_path / "mixed"
    folder.mkdir()
    for name in ("walk_normal_001", "run_normal_001"):
        (folder / f"{name}.bvh").symlink_to(clip_path(name))
    write_variants(clip_path("walk_happy_001"), tmp_path / "rigs")["metres"].rename(folder / "metres.bvh")
    assert main(["build-dataset", str(folder), "--cache-dir", str(tmp_path / "cache")]) == 2
    assert "2 are in cm (such as run_normal_001.bvh, 161.2 units from foot to head), but not metres.bvh (1.462 units: m)" \
        in capsys.readouterr().err
    assert main(["build-dataset", str(folder), "--cache-dir", str(tmp_path / "cache"), "--scale", "cm"]) == 0


def test_natural_exports_every_clip_of_a_folder_without_labels_and_names_short_takes(clip_path, tmp_path, capsys):
    folder = tmp_path / "unlabelled"
    folder.mkdir()
    names = ["walk_normal_001", "walk_happy_001", "walk_old_001", "run_normal_001", "walk_normal_002"]
    for name in names:
        (folder / f"{name}.bvh").symlink_to(clip_path(name))
    out = tmp_path / "NAT"
    assert main(["natural", str(folder), "--split", "train", "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert "take(s) end before 4 s, so their clips are shorter" in said.err  # run_normal_001 lasts 0.8 s
    assert "run_normal_001" in said.err or "walk_normal_002" in said.err
    exported = {p.stem for p in out.glob("*.npz")}
    assert exported and exported <= set(names)
