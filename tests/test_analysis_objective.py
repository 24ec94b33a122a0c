"""Objective metrics: footsteps on real walking, bone lengths, IS / FID, correlation.

How the footstep count was validated on the real data: for each Bandai-Namco walk clip,
an independent count of visible steps is taken from the heel *height* curve, one swing
phase per peak of at least 3 cm (the foot leaving the ground), on both feet. Between
two swings a foot stands once, so the footsteps detected from horizontal heel speed
should number the swings plus at most one extra stance per foot at the clip edges
(plus the occasional stance split in two where a shuffling gait creeps the heel at weight
transfer; sad/old walks). The heel-height and speed curves of walk_active_001,
walk_feminine_002, walk_normal_001, walk_proud_002 and walk_sad_002 were also plotted
with the detected touchdowns drawn in and the swings counted by eye.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.signal import find_peaks

from analysis.motion.bones import bone_length_rmse, rigid_bones
from analysis.stats.correlation import subjective_objective_correlation
from analysis.errors import AnalysisInputError
from analysis.motion.footsteps import FootSpeeds, footstep_summary, footstep_tolerance_curve, step_durations, v_tol_95
from analysis.motion.scores import frechet_distance, inception_score
from analysis.motion.smoothness import mean_joint_acceleration
from measures.feet import choose_foot_joints, find_foot_joints, lower_foot_speed
from measures.units import Z_UP_TO_Y_UP


@pytest.fixture(scope="module")
def walks(motion_data):
    from generation.motion import load_motion

    return [load_motion(p) for p in sorted((motion_data / "data").glob("dataset-1_walk_*.bvh"))]


def test_foot_joints_are_found_by_name():
    names = ["Hips", "UpperLeg_L", "Foot_L", "Toes_L", "UpperLeg_R", "Foot_R", "Toes_R"]
    assert find_foot_joints(names) == ["Foot_L", "Foot_R"]
    assert find_foot_joints(names, "toe") == ["Toes_L", "Toes_R"]
    assert find_foot_joints(["LeftHeel", "RightHeel", "LeftFoot", "RightFoot"]) == ["LeftHeel", "RightHeel"]
    with pytest.raises(ValueError, match="pass the foot joints explicitly"):
        find_foot_joints(["Hips", "Spine"])


def test_detected_footsteps_match_the_visible_steps_of_real_walking(walks):
    feet = [walks[0].skeleton.index(n) for n in find_foot_joints(walks[0].skeleton.names)]
    curve = footstep_tolerance_curve([w.positions for w in walks], walks[0].fps, feet)
    v95 = v_tol_95(curve)
    assert 1.0 <= v95 <= 15.0  # cm/s: mocap feet plant crisply
    # f_est saturates at the step rate of human walking (about 1.4-2.2 steps per second)
    assert 1.4 <= curve["f_est"].max() <= 2.2
    total_detected = total_swings = 0
    for walk in walks:
        if walk.duration < 3.0:
            continue
        detected = int(footstep_tolerance_curve([walk.positions], walk.fps, feet,
                                                np.array([v95]))["footsteps"].iloc[0])
        swings = sum(len(find_peaks(walk.positions[:, f, 1], prominence=3.0)[0]) for f in feet)
        assert swings - 2 <= detected <= swings + 5, (walk.duration, detected, swings)
        total_detected += detected
        total_swings += swings
    assert total_swings <= total_detected <= total_swings * 1.25


def test_step_durations_of_real_walking_are_human(walks):
    feet = [walks[0].skeleton.index(n) for n in ("Foot_L", "Foot_R")]
    summary, _ = footstep_summary([w.positions for w in walks], walks[0].fps, feet)
    # a walking step (one foot's touchdown to the other's) takes about half a second
    assert 0.4 <= summary["step_duration_mean"] <= 0.8
    assert 0.0 < summary["step_duration_sd"] < 0.4


def gait(strides: int, fps: float = 20.0, stride_cm: float = 60.0) -> np.ndarray:
    """Two feet, one stride per second each: 0.4 s swing, 0.6 s stance, feet half a
    stride apart; the clip starts in double support and ends 0.15 s after the last
    touchdown, so every touchdown is a whole footstep."""
    t = np.arange(int(strides * fps) + 3) / fps + 0.95  # phase 0.95: both feet planted
    clip = np.zeros((len(t), 2, 3))
    for foot, shift in ((0, 0.0), (1, 0.5)):
        phase = (t + shift) % 1.0
        speed = np.where(phase < 0.4, np.sin(np.pi * phase / 0.4), 0.0)
        clip[:, foot, 2] = stride_cm * np.cumsum(speed) / speed.sum() * strides
    return clip


def test_footsteps_of_a_sliding_foot_need_a_larger_tolerance():
    clips = [gait(4) for _ in range(3)]
    sliding = [c + 8.0 * (np.arange(len(c)) / 20.0)[:, None, None] * np.array([0, 0, 1.0]) for c in clips]
    crisp = footstep_tolerance_curve(clips, 20.0, [0, 1])
    assert crisp["footsteps"].max() == 3 * 8  # two touchdowns a second for 4 s, 3 clips
    assert v_tol_95(crisp) <= 1.0
    assert 8.0 <= v_tol_95(footstep_tolerance_curve(sliding, 20.0, [0, 1])) <= 10.0
    # alternating feet half a stride apart: half a second between footfalls
    durations = step_durations(clips, 20.0, [0, 1], v_tol_95(crisp))
    assert len(durations) == 3 * 7
    assert durations == pytest.approx(np.full(len(durations), 0.5))


def test_contacts_never_join_across_clips():
    stopping = np.zeros((10, 2, 3))
    stopping[:3, :, 2] = [[0.0], [5.0], [10.0]]  # both feet move, then stand
    stopping[3:, :, 2] = 10.0
    speeds = FootSpeeds([stopping, stopping], 10.0, [0, 1])
    starts = speeds.footstep_starts(np.array([1.0]), 2)[0]
    assert starts.sum() == 4  # each foot touches down once in each clip


def test_no_footsteps_gives_nan_not_an_error():
    flying = np.cumsum(np.full((40, 2, 3), 50.0), axis=0)  # always moving fast
    summary, curve = footstep_summary([flying], 20.0, [0, 1])
    assert np.isnan(summary["v_tol_95"]) and curve["f_est"].max() == 0


def test_bone_length_error_of_natural_data_is_zero_and_grows_with_noise(walks):
    skeleton = walks[0].skeleton
    clips = [w.positions for w in walks[:6]]
    natural = bone_length_rmse(clips, skeleton.parents, skeleton.offsets)
    assert natural < 1e-3
    rng = np.random.default_rng(0)
    errors = [bone_length_rmse([c + rng.normal(0, sd, c.shape) for c in clips],
                               skeleton.parents, skeleton.offsets) for sd in (0.5, 1.0, 2.0, 4.0)]
    assert errors == sorted(errors) and errors[0] > 0.3
    # isotropic 3-D noise of sd s on both ends changes a long bone's length by about s*sqrt(2)
    assert errors[-1] == pytest.approx(4.0 * np.sqrt(2), rel=0.25)


def test_joint_acceleration_is_zero_for_steady_motion_and_matches_a_hand_computation():
    t = np.arange(40)[:, None, None] / 20.0
    steady = np.concatenate([t * [[100.0, 0, 0]], t * [[0, 0, 50.0]]], axis=1)  # two joints at constant velocity
    assert mean_joint_acceleration([steady], 20.0) == pytest.approx(0.0, abs=1e-9)
    # One joint displaced by 1 cm in one frame: second differences 1, -2, 1 around it.
    bumped = steady.copy()
    bumped[10, 0, 1] += 1.0
    frames, joints = 38, 2
    assert mean_joint_acceleration([bumped], 20.0) == pytest.approx((1 + 2 + 1) / (frames * joints) * 400)


def test_lower_foot_speed_tells_a_planted_foot_from_a_gliding_one():
    frames = 21
    planted = np.zeros((frames, 2, 3))
    planted[:, 0] = [0, 0, 0]  # on the floor, still
    planted[:, 1] = np.c_[np.linspace(0, 100, frames), np.full(frames, 10.0), np.zeros(frames)]  # swinging, raised
    assert lower_foot_speed([planted], 20.0, [0, 1]) == pytest.approx(0.0)
    gliding = planted.copy()
    gliding[:, 0, 0] = np.linspace(0, 120, frames)  # the lower foot slides 120 cm in one second
    assert lower_foot_speed([gliding], 20.0, [0, 1]) == pytest.approx(120.0)


def test_natural_walking_has_planted_feet_and_little_jitter(walks):
    from generation.motion.resample import resample

    clips = [resample(w, 20.0) for w in walks[:6]]
    feet = [clips[0].skeleton.index(n) for n in find_foot_joints(clips[0].skeleton.names, "heel")]
    speed = lower_foot_speed([c.positions for c in clips], 20.0, feet)
    walking = np.mean([np.linalg.norm(np.diff(c.positions[:, clips[0].skeleton.index("Hips"), [0, 2]], axis=0),
                                      axis=-1).mean() * 20 for c in clips])
    assert speed < 0.3 * walking  # the weight-bearing heel is nearly still while the body moves
    assert 100 < mean_joint_acceleration([c.positions for c in clips], 20.0) < 1500


def test_the_floor_root_of_bandai_namco_is_not_a_bone(walks):
    skeleton = walks[0].skeleton
    bones = rigid_bones(skeleton.parents, skeleton.offsets)
    assert (0, skeleton.index("Hips")) not in bones
    assert (skeleton.index("Hips"), skeleton.index("Spine")) in bones


def test_inception_score_limits():
    uniform_classes = np.eye(4)[np.arange(400) % 4]  # confident and evenly spread: IS = C
    assert inception_score(uniform_classes) == pytest.approx(4.0)
    assert inception_score(np.full((10, 4), 0.25)) == pytest.approx(1.0)  # no information
    with pytest.raises(AnalysisInputError):
        inception_score(np.full((3, 4), 0.5))


def gaussian_sample(rng, n: int, mean: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """n points whose sample mean and covariance are exactly ``mean`` and diag(sd^2)."""
    centred = rng.normal(size=(n, len(mean)))
    centred -= centred.mean(axis=0)
    orthonormal, _ = np.linalg.qr(centred)  # zero-mean, mutually orthogonal columns
    return mean + orthonormal * np.sqrt(n - 1) * sd


def test_frechet_distance_equals_the_closed_form_for_diagonal_covariances():
    rng = np.random.default_rng(0)
    mu_r, sd_r = np.array([0.0, 1.0, 2.0]), np.array([1.0, 2.0, 0.5])
    mu_g, sd_g = np.array([1.0, 1.0, 0.0]), np.array([1.5, 1.0, 0.5])
    real, generated = gaussian_sample(rng, 500, mu_r, sd_r), gaussian_sample(rng, 300, mu_g, sd_g)
    # with diagonal covariances (S_r S_g)^(1/2) = diag(sd_r sd_g), so
    # FID = |mu_r - mu_g|^2 + sum (sd_r - sd_g)^2 = 5 + 1.25
    assert frechet_distance(real, generated) == pytest.approx(6.25, rel=1e-9)
    assert frechet_distance(real, real) == pytest.approx(0.0, abs=1e-8)


def test_correlation_between_ratings_and_metrics_notes_what_it_cannot_compute():
    ratings = pd.Series({"NAT": 4.2, "A": 3.1, "B": 2.5, "C": 3.6})
    metrics = pd.DataFrame({"v_tol_95": [5.0, 12.0, 20.0, 9.0], "bone_length_rmse": [0.0] * 4},
                           index=["NAT", "A", "B", "C"])
    table, notes = subjective_objective_correlation(ratings, metrics)
    assert table["metric"].tolist() == ["v_tol_95"]
    assert table["r"].iloc[0] < -0.9
    assert any("bone_length_rmse" in n and "constant" in n for n in notes)


def test_feet_are_the_lowest_end_joints_when_names_say_nothing(walks):
    skeleton = walks[0].skeleton
    nameless = [f"J{j}" for j in range(skeleton.n_joints)]
    clips = [w.positions for w in walks[:3]]
    feet = choose_foot_joints(nameless, skeleton.parents, clips)
    assert feet == [skeleton.index("Toes_L"), skeleton.index("Toes_R")]
    assert choose_foot_joints(skeleton.names, skeleton.parents, clips) == [skeleton.index("Foot_L"), skeleton.index("Foot_R")]
    assert choose_foot_joints(nameless, skeleton.parents, clips, given=["J2"]) == [2]
    with pytest.raises(ValueError, match="no joint.* Heel_L"):
        choose_foot_joints(nameless, skeleton.parents, clips, given=["Heel_L"])


def test_objective_metrics_of_motion_in_metres_with_z_up_equal_those_in_centimetres(walks, tmp_path, capsys):
    from analysis.cli import main
    from analysis.motion.motion_io import save_clips

    skeleton = walks[0].skeleton
    for name, scale, rotation in (("cm", 1.0, np.eye(3)), ("m-z-up", 0.01, Z_UP_TO_Y_UP.T)):
        (tmp_path / name / "NAT").mkdir(parents=True)
        for k, walk in enumerate(walks[:4]):
            save_clips(tmp_path / name / "NAT" / f"{k}.npz", walk.positions @ rotation.T * scale, walk.fps,
                       skeleton.names, skeleton.parents, skeleton.offsets * scale)
        assert main(["objective", str(tmp_path / name), "--out", str(tmp_path / f"out-{name}")]) == 0
    said = capsys.readouterr().out
    assert "motion units: cm, y up" in said and "motion units: m, z up" in said
    tables = [pd.read_csv(tmp_path / f"out-{name}" / "tables" / "objective_metrics.csv") for name in ("cm", "m-z-up")]
    pd.testing.assert_frame_equal(tables[0], tables[1], rtol=1e-4, atol=1e-4)  # float32 files
    assert tables[0]["steps_per_s"].iloc[0] > 1.0
