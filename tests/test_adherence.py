"""Control adherence: constructed motion with a known position and heading error, written
as ``python -m generation`` writes clips, measured by ``python -m analysis objective``."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from statsmodels.stats.proportion import proportion_confint

from analysis.reports.adherence import label_adherence, path_adherence, path_errors
from analysis.reports.attribute_scores import ClassifierOutputs
from analysis.cli import main
from analysis.errors import AnalysisInputError
from analysis.motion.motion_io import FollowedPath, load_motion_sets
from analysis.ratings.simulate import simulate_appropriateness
from generation.control import following_arrays, preset_path
from generation.motion.npz import save_motion_npz
from generation.motion.root import RootTrajectory
from generation.motion.types import Motion
from generation.render.synthetic import SKELETON

CONTROLS = ("walk-circle", "walk-zigzag")


def rest_pose() -> np.ndarray:
    """The synthetic figure's joints (J, 3) standing at the origin facing +z, x to its left."""
    pose = np.zeros((SKELETON.n_joints, 3))
    for j, parent in enumerate(SKELETON.parents):
        pose[j] = (pose[parent] if parent >= 0 else 0.0) + SKELETON.offsets[j]
    return pose


def figure_along(path: RootTrajectory, offset: np.ndarray, heading_error: float) -> Motion:
    """A rigid figure carried along ``path`` displaced by ``offset`` (frames, 2) cm and
    facing ``heading_error`` degrees left of the path's facing."""
    yaw = path.yaw + np.radians(heading_error)
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    local = rest_pose()
    positions = np.stack([c * local[:, 0] + s * local[:, 2], np.tile(local[:, 1], (len(yaw), 1)),
                          -s * local[:, 0] + c * local[:, 2]], axis=-1)
    positions[..., 0] += (path.xz[:, 0] + offset[:, 0])[:, None]
    positions[..., 2] += (path.xz[:, 1] + offset[:, 1])[:, None]
    return Motion(positions, 20.0, SKELETON)


def write_system(folder, system: str, offset_at, heading_error: float) -> None:
    for name in CONTROLS:
        path = preset_path(name).path()
        motion = figure_along(path, offset_at(len(path.xz)), heading_error)
        save_motion_npz(motion, folder / system / f"{name}.npz", **following_arrays(motion, path))


def constant(cm: float):
    return lambda frames: np.tile([cm, 0.0], (frames, 1))


def drifting(cm_at_end: float):
    return lambda frames: np.column_stack([np.zeros(frames), np.linspace(0.0, cm_at_end, frames)])


@pytest.fixture(scope="module")
def motion_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("motion")
    write_system(folder, "Exact", constant(0.0), 0.0)
    write_system(folder, "Offset", constant(40.0), 15.0)
    write_system(folder, "Drifting", drifting(120.0), -30.0)
    return folder


def test_a_known_offset_and_heading_error_are_measured_over_time_and_at_the_end(motion_folder):
    table, curves, notes = path_adherence(load_motion_sets([motion_folder]))
    table = table.set_index("system")
    assert notes == [] and table["n_clips"].tolist() == [2, 2, 2]
    # The root is the models' (the hips' floor projection smoothed over 0.1 s, the facing over
    # 0.25 s): exact all along, but at a clip's last frames on a curve it lags a few cm and
    # degrees behind (so does natural motion's; NAT shows that floor).
    assert table.at["Exact", "position_error_mean"] < 1.0 and table.at["Exact", "heading_error_mean"] < 1.5
    assert table.at["Exact", "position_error_end"] < 5.0 and table.at["Exact", "heading_error_end"] < 5.0
    assert table.at["Offset", "position_error_mean"] == pytest.approx(40.0, abs=1.0)
    assert table.at["Offset", "position_error_end"] == pytest.approx(40.0, abs=3.0)
    assert table.at["Offset", "heading_error_mean"] == pytest.approx(15.0, abs=0.5)
    assert table.at["Offset", "heading_error_end"] == pytest.approx(15.0, abs=5.0)
    assert table.at["Drifting", "position_error_mean"] == pytest.approx(60.0, abs=1.5)  # a linear drift averages half
    assert table.at["Drifting", "position_error_end"] == pytest.approx(120.0, abs=3.0)
    assert table.at["Drifting", "heading_error_end"] == pytest.approx(30.0, abs=5.0)
    drift = curves[curves["system"] == "Drifting"]
    assert drift["time_s"].iloc[-1] == pytest.approx(79 / 20)
    assert np.allclose(drift["position_error"], np.linspace(0, 120, 80), atol=6.0)


def test_heading_errors_wrap_to_the_smaller_angle():
    frames = 3
    followed = FollowedPath(np.zeros((frames, 2)), np.radians([170.0, -170.0, 0.0]), np.zeros((frames, 2)),
                            np.radians([-170.0, 170.0, 359.0]))
    _, heading = path_errors(followed)
    assert heading == pytest.approx([20.0, 20.0, 1.0])


def test_objective_writes_adherence_and_correlates_it_with_appropriateness(motion_folder, tmp_path, capsys):
    ratings = simulate_appropriateness({"Exact": 0.9, "Offset": 0.75, "Drifting": 0.6}, n_participants=60,
                                       inattentive_share=0.0, seed=2)
    ratings.to_csv(tmp_path / "ratings.csv", index=False)
    out = tmp_path / "objective"
    assert main(["objective", str(motion_folder), "--out", str(out), "--appropriateness",
                 str(tmp_path / "ratings.csv")]) == 0, capsys.readouterr().err
    for name in ("control_adherence.csv", "adherence_over_time.csv", "adherence_correlation.csv"):
        assert (out / "tables" / name).is_file()
    assert (out / "figures" / "adherence_over_time.svg").is_file()
    correlation = pd.read_csv(out / "tables" / "adherence_correlation.csv").set_index("metric")
    assert correlation.at["position_error_mean", "n_systems"] == 3
    assert correlation.at["position_error_mean", "r"] < -0.9  # more error, lower scores


def test_objective_refuses_a_ratings_table_of_another_design(motion_folder, tmp_path, capsys):
    pd.DataFrame({"participant": ["p1", "p1"], "system": ["Exact", "Offset"], "stimulus": ["a", "b"],
                  "value": [4, 3], "scale_min": [1, 1], "scale_max": [5, 5]}).to_csv(tmp_path / "r.csv", index=False)
    assert main(["objective", str(motion_folder), "--out", str(tmp_path / "o"), "--appropriateness",
                 str(tmp_path / "r.csv")]) == 2
    assert "is a single table; give an appropriateness table" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_clip_with_some_of_the_control_arrays_is_refused_naming_the_missing(tmp_path):
    motion = figure_along(preset_path("walk-circle").path(), np.zeros((80, 2)), 0.0)
    arrays = following_arrays(motion, preset_path("walk-circle").path())
    save_motion_npz(motion, tmp_path / "A" / "clip.npz", control_path=arrays["control_path"])
    with pytest.raises(AnalysisInputError, match="has control_path but not control_yaw, root_path, root_yaw"):
        load_motion_sets([tmp_path])
    save_motion_npz(motion, tmp_path / "A" / "clip.npz", **{**arrays, "root_yaw": arrays["root_yaw"][:-1]})
    with pytest.raises(AnalysisInputError, match=r"root_yaw must be \(80,\) for positions of 80 frames"):
        load_motion_sets([tmp_path])


def test_label_adherence_is_the_share_recognised_with_its_wilson_interval():
    rng = np.random.default_rng(0)
    asked = rng.integers(0, 3, 50)
    probabilities = rng.random((50, 3))
    probabilities[np.arange(35), asked[:35]] = 2.0  # the first 35 recognised, the rest by chance
    arrays = {"action": asked, "style": asked, "action_probabilities": probabilities,
              "style_probabilities": probabilities}
    table = label_adherence(ClassifierOutputs({"HVRNN": arrays}, "HVRNN", ("a", "b", "c"), ("a", "b", "c")))
    right = int((probabilities.argmax(axis=1) == asked).sum())
    row = table.iloc[0]
    assert row["n"] == 50 and row["action_accuracy"] == right / 50 and right >= 35
    assert (row["action_ci_low"], row["action_ci_high"]) == pytest.approx(
        proportion_confint(right, 50, method="wilson"), abs=1e-12)
