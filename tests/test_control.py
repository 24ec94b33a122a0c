"""Control signals: synthetic paths integrate to the shapes they describe; held-out ones are real."""

from __future__ import annotations

import json

import numpy as np
import pytest

from generation.control import (
    PRESETS,
    PathControl,
    control_from_dict,
    held_out_paths,
    in_control_frame,
    load_control_file,
    preset_path,
    synthetic_path,
)


def test_straight_walk_covers_speed_times_time_facing_forward():
    path = preset_path("walk-straight").path()
    assert path.xz[-1, 1] == pytest.approx(120 * 79 / 20)  # 80 frames, 79 steps at 120 cm/s
    assert np.abs(path.xz[:, 0]).max() < 1e-9 and np.abs(path.yaw).max() < 1e-12


def test_circle_turns_at_the_asked_rate():
    control = preset_path("walk-circle")
    assert np.degrees(control.path().yaw[-1]) == pytest.approx(45 * 79 / 20)


def test_sidestep_moves_sideways_and_backward_moves_back():
    left = preset_path("sidestep-left").path().xz[-1]
    right = preset_path("sidestep-right").path().xz[-1]
    assert left[0] > 200 and right[0] < -200  # +x is the character's left at yaw 0
    assert preset_path("walk-backward").path().xz[-1, 1] < -300


def test_stand_still_stays_put_and_segments_join_smoothly():
    assert np.abs(preset_path("stand-still").path().xz).max() == 0
    speed = preset_path("walk-stop-walk").velocities[:, 0]
    assert speed.max() == pytest.approx(120, abs=1) and speed.min() < 2
    assert np.abs(np.diff(speed)).max() < 30  # cm/s per frame: no jump from 120 to 0


def test_every_preset_builds():
    for name in PRESETS:
        control = preset_path(name)
        assert control.n_frames >= 60 and np.isfinite(control.velocities).all()


def test_json_and_yaml_files_describe_paths(tmp_path):
    (tmp_path / "paths.json").write_text(json.dumps([{"segments": [{"type": "ramp", "from": 0, "to": 200, "seconds": 2}]}]))
    (tmp_path / "turn.yaml").write_text("segments:\n  - {type: curve, speed: 100, turn_rate: -30, seconds: 3}\n")
    ramp = load_control_file(tmp_path / "paths.json")[0]
    assert ramp.velocities[0, 0] == pytest.approx(0) and ramp.velocities[-1, 0] == pytest.approx(200)
    turn = load_control_file(tmp_path / "turn.yaml")[0]
    assert turn.path().yaw[-1] < 0 and turn.name == "turn-0"


@pytest.mark.parametrize("text, message", [
    ('{"segments": []}', "non-empty 'segments'"),
    ('{"segments": [{"type": "fly", "seconds": 1}]}', "unknown segment type 'fly'"),
    ('{"segments": [{"type": "straight"}]}', "positive 'seconds'"),
    ('{"segments": [{"type": "straight", "seconds": 1},]}', "invalid JSON"),
])
def test_bad_descriptions_name_the_problem(tmp_path, text, message):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_control_file(path)


def test_controls_round_trip_through_dicts():
    control = synthetic_path({"name": "x", "segments": [{"type": "curve", "seconds": 1}]})
    again = control_from_dict(json.loads(json.dumps(control.to_dict())))
    assert isinstance(again, PathControl) and again.name == "x"
    np.testing.assert_allclose(again.velocities, control.velocities, atol=1e-4)


def test_held_out_control_comes_from_held_out_natural_clips(motion_data, tmp_path):
    from generation.motion.dataset import build_dataset
    from generation.motion.dataset_options import DatasetOptions

    dataset = build_dataset(motion_data, DatasetOptions(contents=("walk-back",)), cache_dir=tmp_path, progress=False)
    controls = held_out_paths(dataset, seconds=4)
    assert {c.name for c in controls} == {c.name for c in dataset.select("test")}
    assert all(c.n_frames <= 80 for c in controls)
    assert all(c.velocities[:, 0].mean() < -30 for c in controls)  # walking backwards


def test_a_lead_in_is_the_warm_up_and_without_one_the_first_frame_is_held():
    velocities = np.arange(30.0).reshape(10, 3)
    plain = PathControl(velocities, 20.0)
    assert np.array_equal(plain.warmup(4), np.repeat(velocities[:1], 4, axis=0))
    lead = np.arange(100.0, 115.0).reshape(5, 3)
    led = PathControl(velocities, 20.0, lead_in=lead)
    assert np.array_equal(led.warmup(3), lead[-3:])  # the end of a longer lead-in
    assert np.array_equal(led.warmup(7), np.concatenate([lead[:1], lead[:1], lead]))  # a shorter one, its start held
    assert led.warmup(0).shape == (0, 3)


def test_a_lead_in_round_trips_and_a_control_without_one_keeps_its_dict():
    control = PathControl(np.ones((4, 3)), 20.0, "take", lead_in=np.zeros((2, 3)))
    again = control_from_dict(json.loads(json.dumps(control.to_dict())))
    assert np.array_equal(again.lead_in, control.lead_in)
    assert "lead_in" not in PathControl(np.ones((4, 3)), 20.0).to_dict()  # digests of existing stimuli unchanged
    with pytest.raises(ValueError, match="lead-in needs finite values of shape"):
        PathControl(np.ones((4, 3)), 20.0, lead_in=np.full((2, 3), np.nan))


def test_held_out_control_with_a_lead_in_starts_that_far_into_each_take(motion_data, tmp_path):
    from generation.motion.dataset import build_dataset
    from generation.motion.dataset_options import DatasetOptions

    dataset = build_dataset(motion_data, DatasetOptions(contents=("walk-back",)), cache_dir=tmp_path, progress=False)
    plain, led = held_out_paths(dataset, seconds=None), held_out_paths(dataset, seconds=2, lead_in_seconds=1)
    assert [c.name for c in led] == [c.name for c in plain]
    for whole, control in zip(plain, led):
        assert np.array_equal(control.lead_in, whole.velocities[:20])
        assert np.array_equal(control.velocities, whole.velocities[20:60])
    with pytest.raises(ValueError, match="the lead-in must be 0 or more seconds"):
        held_out_paths(dataset, seconds=2, lead_in_seconds=-1)


def test_a_natural_take_moved_into_its_controls_frame_walks_along_its_controls_path(motion_data, tmp_path):
    from generation.motion.clip_files import load_body_motion
    from generation.motion.dataset import build_dataset
    from generation.motion.dataset_options import DatasetOptions
    from generation.motion.root import root_trajectory

    dataset = build_dataset(motion_data, DatasetOptions(contents=("walk-left",)), cache_dir=tmp_path, progress=False)
    options = dataset.options
    for control in held_out_paths(dataset, seconds=4):
        take = load_body_motion(motion_data / "data" / f"{control.name}.bvh", options.fps, 4.0, options.scale,
                                options.root, options.up)
        assert np.linalg.norm(root_trajectory(take, options.root).xz[0]) > 50  # the take starts elsewhere
        root = root_trajectory(in_control_frame(take, options.root), options.root)
        assert np.allclose(root.xz[0], 0.0, atol=1e-6) and abs(root.yaw[0]) < 1e-6
        # within a few cm of the path all along (the take's root is smoothed over the whole take for
        # its control, over the cut clip here)
        assert np.linalg.norm(root.xz - control.path().xz, axis=1).max() < 10.0
        assert np.abs(root.yaw - control.path().yaw).max() < np.radians(5)
