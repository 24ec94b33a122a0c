"""Objective metrics against the raters: the Fréchet distance of pose features against
independent computations, Kendall's tau over systems and clips against scipy on tables
built by hand, and the report of a study with its motion."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import linalg
from scipy import stats as sps

from analysis.cli import main
from analysis.motion.frechet import frechet_distance, gaussian_frechet, pose_features
from analysis.rankings.leaderboard import INTERVAL_WARNING_PARTICIPANTS
from analysis.reports.metric_agreement import clip_metrics, clip_stimulus, kendall_tau_rows, metric_agreement
from analysis.motion.motion_io import load_motion_sets, save_clips


def sqrtm_frechet(a: np.ndarray, b: np.ndarray) -> float:
    """The textbook formula with scipy's general matrix square root."""
    mu_a, mu_b = a.mean(axis=0), b.mean(axis=0)
    cov_a, cov_b = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    return float(((mu_a - mu_b) ** 2).sum() + np.trace(cov_a + cov_b - 2.0 * linalg.sqrtm(cov_a @ cov_b).real))


def test_the_frechet_distance_of_correlated_features_equals_scipys_matrix_square_root():
    rng = np.random.default_rng(1)
    mixing = rng.normal(size=(6, 6))
    a = rng.normal(size=(400, 6)) @ mixing
    b = rng.normal(size=(250, 6)) @ (mixing + 0.3 * rng.normal(size=(6, 6))) + 0.5
    assert frechet_distance(a, b) == pytest.approx(sqrtm_frechet(a, b), rel=1e-8)
    assert frechet_distance(a, a) == pytest.approx(0.0, abs=1e-8)


def test_the_frechet_distance_of_diagonal_gaussians_is_the_closed_form():
    mu1, mu2 = np.array([0.0, 1.0, 2.0]), np.array([1.0, 1.0, 0.0])
    var1, var2 = np.array([1.0, 4.0, 0.25]), np.array([2.25, 1.0, 0.25])
    # (S1 S2)^(1/2) = diag(sd1 sd2): the distance is |mu1 - mu2|^2 + sum (sd1 - sd2)^2 = 5 + 1.25
    assert gaussian_frechet(mu1, np.diag(var1), mu2, np.diag(var2)) == pytest.approx(6.25, rel=1e-12)


def test_a_singular_covariance_gives_a_finite_distance_and_a_shift_its_square():
    rng = np.random.default_rng(2)
    poses = rng.normal(size=(50, 4, 3))
    features = pose_features(poses, np.array([-1, 0, 1, 2]))
    assert np.allclose(features[:, :3], 0.0)  # the root's own columns: a singular covariance
    assert frechet_distance(features, features + np.r_[0.0, 0.0, 0.0, [1.0, 2.0, 2.0] * 3]) == pytest.approx(27.0)


def tidy(values: dict[tuple[str, str], dict[str, float]]) -> pd.DataFrame:
    return pd.DataFrame([{"system": s, "stimulus": c, "metric": m, "value": v}
                         for (s, c), metrics in values.items() for m, v in metrics.items()])


@pytest.fixture(scope="module")
def study() -> tuple[pd.DataFrame, pd.DataFrame]:
    """Four systems of three clips; the ratings fall with a system's jerk, foot sliding is noise."""
    rng = np.random.default_rng(4)
    quality = {"NAT": 4.3, "A": 3.6, "B": 3.0, "C": 2.2}
    metrics, rows = {}, []
    for system, level in quality.items():
        for k in range(3):
            clip = f"{system}_{k}"
            metrics[(system, clip)] = {"jerk": 10 * (5 - level) + rng.normal(0, 1), "foot_sliding": rng.normal(5, 1)}
            for participant in range(15):
                rows.append({"participant": f"p{participant}", "system": system, "stimulus": clip,
                             "value": int(np.clip(round(level + rng.normal(0, 0.8)), 1, 5))})
    return tidy(metrics), pd.DataFrame(rows)


def test_the_tau_over_systems_and_clips_equals_scipy_on_the_means(study):
    metrics, ratings = study
    agreement, per_system, notes = metric_agreement(metrics, ratings, resamples=300, seed=1)
    assert notes == []
    for metric in ("jerk", "foot_sliding"):
        row = agreement.set_index("metric").loc[metric]
        values = metrics[metrics["metric"] == metric]
        system_means = values.groupby("system")["value"].mean()
        ratings_means = ratings.groupby("system")["value"].mean()[system_means.index]
        assert row["tau"] == pytest.approx(sps.kendalltau(system_means, ratings_means).statistic)
        clip_means = ratings.groupby("stimulus")["value"].mean()[values["stimulus"]]
        expected = sps.kendalltau(values["value"].to_numpy(), clip_means.to_numpy())
        assert (row["clip_tau"], row["clip_p"]) == pytest.approx((expected.statistic, expected.pvalue))
        assert row["n_systems"] == 4 and row["n_clips"] == 12 and row["resamples_used"] == 300
        assert row["ci_low"] <= row["tau"] <= row["ci_high"]
    jerk = agreement.set_index("metric").loc["jerk"]
    assert jerk["tau"] == -1.0 and jerk["ci_high"] < 0  # the raters follow the jerk
    assert set(per_system["system"]) == {"NAT", "A", "B", "C"}
    again, _, _ = metric_agreement(metrics, ratings, resamples=300, seed=1)
    pd.testing.assert_frame_equal(agreement, again)


def test_the_bootstraps_tau_of_many_rows_at_once_equals_scipys_tau_b_with_ties():
    rng = np.random.default_rng(5)
    x, y = rng.integers(0, 4, size=(200, 6)).astype(float), rng.integers(0, 3, size=(200, 6)).astype(float)
    expected = [sps.kendalltau(a, b).statistic for a, b in zip(x, y)]
    np.testing.assert_allclose(kendall_tau_rows(x, y), expected, rtol=1e-12, equal_nan=True)


def test_a_metric_of_fewer_than_three_rated_systems_is_noted_not_correlated(study):
    metrics, ratings = study
    few = metrics[metrics["system"].isin(["NAT", "A"]) | (metrics["metric"] == "jerk")]
    agreement, _, notes = metric_agreement(few, ratings, resamples=20)
    assert list(agreement["metric"]) == ["jerk"]
    assert notes == ["No agreement for foot_sliding: 2 system(s) have both the metric and ratings (3 or more needed)."]


def test_a_metric_the_same_for_every_system_is_noted_not_correlated(study):
    metrics, ratings = study
    constant = metrics.assign(value=np.where(metrics["metric"] == "foot_sliding", 1.0, metrics["value"]))
    agreement, _, notes = metric_agreement(constant, ratings, resamples=20)
    assert list(agreement["metric"]) == ["jerk"]
    assert notes == ["No agreement for foot_sliding: the metric or the mean rating is the same for every system."]


def test_clips_are_named_by_their_file_stem():
    assert clip_stimulus("motion/MoGlow/walk_03.npz") == "walk_03"
    assert clip_stimulus("motion/MoGlow.npz[2]") == "MoGlow[2]"


def test_clip_metrics_give_every_clip_its_metrics_and_its_frechet_distance_to_natural(tmp_path, motion_data):
    from generation.motion import load_motion

    walk = load_motion(sorted((motion_data / "data").glob("dataset-1_walk_*_001.bvh"))[0])
    rng = np.random.default_rng(0)
    for system, noise in (("NAT", 0.0), ("MoGlow", 2.0)):
        (tmp_path / system).mkdir()
        positions = walk.positions + rng.normal(0, noise, walk.positions.shape)
        save_clips(tmp_path / system / f"{system}_walk.npz", positions, walk.fps, walk.skeleton.names,
                   walk.skeleton.parents, walk.skeleton.offsets)
    motion = load_motion_sets([tmp_path])
    table, notes = clip_metrics(motion)
    assert notes == []
    values = table.set_index(["system", "metric"])["value"]
    assert set(table["stimulus"]) == {"NAT_walk", "MoGlow_walk"}
    assert values[("NAT", "frechet_to_natural")] == pytest.approx(0.0, abs=1e-6)
    features = pose_features(motion["MoGlow"].clips[0], motion["MoGlow"].parents)
    natural = pose_features(motion["NAT"].clips[0], motion["NAT"].parents)
    assert values[("MoGlow", "frechet_to_natural")] == pytest.approx(frechet_distance(features, natural), rel=1e-12)
    # A real clip's covariance is singular (the root's own columns are zero, and the frames of a rigid skeleton
    # span fewer dimensions than its features), where any square root is ill-conditioned: the two agree to 1e-4.
    moving = natural.std(axis=0) > 0
    assert values[("MoGlow", "frechet_to_natural")] == pytest.approx(
        sqrtm_frechet(features[:, moving], natural[:, moving]), rel=1e-4)
    assert values[("MoGlow", "joint_acceleration")] > values[("NAT", "joint_acceleration")]
    assert {"foot_sliding", "bone_length_rmse"} <= set(table["metric"])


def test_the_report_of_a_study_with_its_motion_writes_the_agreement_table_and_plot(tmp_path, motion_data):
    from generation.motion import load_motion

    walks = [load_motion(p) for p in sorted((motion_data / "data").glob("dataset-1_walk_*_001.bvh"))[:3]]
    rng = np.random.default_rng(3)
    rows = []
    for system, noise, level in (("NAT", 0.0, 4.4), ("MoGlow", 0.5, 3.8), ("LSTM", 3.0, 2.1), ("VAE", 1.5, 3.0)):
        (tmp_path / "motion" / system).mkdir(parents=True)
        for i, walk in enumerate(walks):
            save_clips(tmp_path / "motion" / system / f"{system}_{i}.npz",
                       walk.positions + rng.normal(0, noise, walk.positions.shape), walk.fps, walk.skeleton.names,
                       walk.skeleton.parents, walk.skeleton.offsets)
            rows += [{"participant": f"p{p}", "system": system, "stimulus": f"{system}_{i}",
                      "value": int(np.clip(round(level + rng.normal(0, 0.7)), 1, 5)), "scale_min": 1, "scale_max": 5}
                     for p in range(12)]
    pd.DataFrame(rows).to_csv(tmp_path / "ratings.csv", index=False)
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "ratings.csv"), "--out", str(out), "--motion", str(tmp_path / "motion"),
                 "--scale", "cm"]) == 0
    agreement = pd.read_csv(out / "tables" / "metric_agreement.csv").set_index("metric")
    assert {"frechet_to_natural", "joint_acceleration", "foot_sliding"} <= set(agreement.index)
    assert (agreement["n_systems"] == 4).all() and (agreement["n_clips"] == 12).all()
    assert agreement.loc["joint_acceleration", "tau"] == -1.0  # the noisier, the jerkier and the worse rated
    assert (out / "figures" / "metric_agreement.png").stat().st_size > 0
    assert "Kendall's tau" in (out / "tables" / "metric_agreement.md").read_text()
    assert "**Objective metrics against the raters.**" in (out / "summary.md").read_text()
    assert not agreement["few_participants"].any()


def test_an_interval_from_fewer_than_ten_participants_is_flagged(study):
    metrics, ratings = study
    few = ratings[ratings["participant"].isin([f"p{i}" for i in range(INTERVAL_WARNING_PARTICIPANTS - 1)])]
    agreement, _, notes = metric_agreement(metrics, few, resamples=50)
    assert agreement["few_participants"].all() and set(agreement["participants"]) == {9}
    assert notes[0] == ("Agreement of foot_sliding: its interval comes from 9 participants, fewer than 10; read it "
                        "as rough (few_participants in the table).")
