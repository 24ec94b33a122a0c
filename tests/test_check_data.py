"""``python -m generation check-data``: the takes expected, found and differing, and which committed models apply."""

from __future__ import annotations

import shutil
from pathlib import Path

from generation.cli import main


def a_copy(folder: Path, tmp_path: Path) -> Path:
    copy = tmp_path / folder.name
    shutil.copytree(folder / "data", copy / "data")
    return copy


def test_the_shared_data_is_the_data_every_committed_model_learnt_from(motion_data, motion_data_2, capsys):
    assert main(["check-data", str(motion_data), str(motion_data_2)]) == 0
    out = capsys.readouterr().out
    assert "holds bandai-namco-1 (174 takes expected, 174 found): every take as expected" in out
    assert "holds bandai-namco-2-locomotion (938 takes expected, 938 found): every take as expected" in out
    assert out.count(": applies: it learnt from exactly these 1043 takes") == 4
    assert "make demo uses the committed models and trains nothing" in out


def test_a_missing_a_changed_and_an_unexpected_take_are_named_and_the_models_do_not_apply(
        motion_data, motion_data_2, tmp_path, capsys):
    folder = a_copy(motion_data, tmp_path)
    (folder / "data" / "dataset-1_walk_normal_001.bvh").unlink()
    changed = folder / "data" / "dataset-1_run_normal_001.bvh"
    changed.write_text(changed.read_text() + "\n")
    shutil.copy(folder / "data" / "dataset-1_walk_active_001.bvh", folder / "data" / "my-own-take.bvh")
    assert main(["check-data", str(folder), str(motion_data_2)]) == 1
    out = capsys.readouterr().out
    assert (f"{folder} holds bandai-namco-1 (174 takes expected, 174 found): 1 missing "
            "(dataset-1_walk_normal_001.bvh); 1 differ in their BVH or labels (dataset-1_run_normal_001.bvh); "
            "1 not expected (my-own-take.bvh)") in out
    assert "models/moglow-cpu.safetensors: does not apply: it learnt from other takes" in out
    assert "DEMO_TRAIN=1 make demo trains its own on this data" in out


def test_a_folder_given_alone_names_the_data_set_not_given(motion_data, capsys):
    assert main(["check-data", str(motion_data)]) == 1
    assert "bandai-namco-2-locomotion: not among the folders given (938 takes expected)" in capsys.readouterr().out


def test_a_folder_of_other_motion_is_told_apart_from_the_bandai_namco_takes(motion_data, motion_data_2, tmp_path,
                                                                            capsys):
    other = tmp_path / "lab"
    other.mkdir()
    shutil.copy(motion_data / "data" / "dataset-1_walk_active_001.bvh", other / "lab_walk_01.bvh")
    assert main(["check-data", str(other)]) == 1
    assert f"{other}: 1 BVH files, none of them a take of the Bandai-Namco data" in capsys.readouterr().out


def test_a_folder_that_does_not_exist_is_an_error_naming_it(tmp_path, capsys):
    assert main(["check-data", str(tmp_path / "nowhere")]) == 2
    assert f"motion folder {tmp_path / 'nowhere'} does not exist" in capsys.readouterr().err
