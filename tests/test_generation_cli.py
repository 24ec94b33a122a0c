"""The generation command line on real clips and on malformed input."""

from __future__ import annotations

import json

import numpy as np

from generation.cli import main
from generation.gallery import GalleryOptions, build_gallery


def test_info_describes_a_real_clip(clip_path, capsys):
    assert main(["info", str(clip_path("walk_normal_001"))]) == 0
    out = capsys.readouterr().out
    assert "195 frames at 30 fps" in out and "Toes_R" in out


def test_render_writes_a_video_and_sheet(clip_path, tmp_path):
    target = tmp_path / "clips" / "walk.mp4"
    assert main(["render", str(clip_path("walk_normal_001")), "-o", str(target), "--sheet", "--size", "320x240"]) == 0
    assert target.stat().st_size > 10_000 and target.with_suffix(".png").is_file()


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
        assert entry["frames"] == 20 and entry["fps"] == 20.0
    # Rendering again reuses the files.
    before = {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("*.mp4")}
    build_gallery(motion_data, tmp_path, options, progress=False)
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("*.mp4")} == before
    assert np.isfinite([e["frames"] for e in entries]).all()


def test_natural_clips_export_feeds_the_objective_metrics(motion_data, tmp_path, capsys):
    from analysis.cli import main as analysis_main

    out = tmp_path / "motion" / "NAT"
    assert main(["natural", str(motion_data), "--contents", "walk", "--out", str(out), "--cache-dir", str(tmp_path)]) == 0
    clips = sorted(out.glob("*.npz"))
    assert clips and all(np.load(c)["positions"].shape == (80, 21, 3) for c in clips)
    capsys.readouterr()
    assert analysis_main(["objective", str(tmp_path / "motion"), "--out", str(tmp_path / "objective")]) == 0
    table = (tmp_path / "objective" / "tables" / "objective_metrics.csv").read_text()
    assert table.startswith("system,n_clips,v_tol_95,steps_per_s")
    assert "NAT" in table and (tmp_path / "objective" / "figures" / "footstep_curves.png").is_file()
