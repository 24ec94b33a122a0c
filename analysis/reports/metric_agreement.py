"""Do the objective metrics agree with the raters? Each metric per clip, its rank
correlation with the human scores over systems, and per clip with the clip's mean rating.

GENEA 2022 found only one numerical measure (FGD) correlating with human-likeness; this is
that check for a study whose motion is stored.

Per clip (`clip_metrics`, a tidy table: system, stimulus, metric, value): foot sliding
(the lowest foot's horizontal speed, `measures.feet.lower_foot_speed`), the mean joint
acceleration (`analysis.motion.smoothness`), the bone-length error (with offsets), the path
adherence (clips that carry their control path: the root's mean distance from it and mean
heading error) and the Fréchet distance of the clip's pose features to all of the natural
system's frames (`analysis.motion.frechet`). A clip's stimulus is its file's stem (``FILE[k]``
for the k-th clip of a stack); the ratings name it so in their ``clip`` column (the study
app's export: ``stimulus`` there is the clip's opaque token) or else in ``stimulus``.

Agreement (`metric_agreement`): a system's metric is the mean over its clips, its score
the mean of its ratings; Kendall's tau-b between them over the systems having both, with a
percentile interval from a bootstrap that draws participants with replacement and, within
each system, clips with replacement (a clip drawn twice counts twice in both the metric's
mean and, through its ratings, the score). Lower is better for every metric here, so a
metric that agrees with the raters has a negative tau. Per clip: Kendall's tau between the
clip's metric and its mean rating over every clip the ratings name. Intervals from fewer
than `analysis.rankings.leaderboard.INTERVAL_WARNING_PARTICIPANTS` participants are flagged.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats as sps

from analysis.reports.adherence import path_errors
from analysis.motion.bones import bone_length_rmse
from analysis.errors import AnalysisInputError
from analysis.motion.frechet import frechet_distance, pose_features
from analysis.rankings.leaderboard import INTERVAL_WARNING_PARTICIPANTS
from analysis.motion.motion_io import SystemClips
from analysis.motion.smoothness import mean_joint_acceleration
from measures.feet import choose_foot_joints, lower_foot_speed

RESAMPLES = 2_000
MIN_POINTS = 3  # a rank correlation over fewer systems or clips says nothing
_CHUNK = 250  # resamples drawn at once: (chunk, participant-clip cells) weights stay small
AGREEMENT_CAPTION = ("Kendall's tau of each objective metric's system means with the systems' mean ratings "
                     "(95 % bootstrap interval over participants and clips; lower is better for every metric, "
                     "so agreement is negative) and, per clip, with the clip's mean rating.")
AGREEMENT_COLUMNS = ["metric", "tau", "ci_low", "ci_high", "n_systems", "participants", "few_participants",
                     "resamples_used", "clip_tau", "clip_p", "n_clips"]


def clip_stimulus(source: str) -> str:
    """The stimulus id of a clip read from ``source`` (``DIR/x.npz`` or ``DIR/x.npz[k]``)."""
    path, bracket, index = source.partition("[")
    return Path(path).stem + (f"[{index}" if bracket else "")


def clip_metrics(motion: dict[str, SystemClips], natural: str = "NAT", foot_joints: Sequence[str] | None = None,
                 foot_kind: str = "heel") -> tuple[pd.DataFrame, list[str]]:
    """Every clip's objective metrics as a tidy table (system, stimulus, metric, value) and
    notes on what was not computed."""
    rows, notes = [], []
    reference = motion.get(natural)
    if reference is None:
        notes.append(f"No Fréchet distance: the motion has no {natural} clips to compare with.")
    else:
        natural_features = np.concatenate([pose_features(c, reference.parents) for c in reference.clips])
    for system, clips in sorted(motion.items()):
        try:
            feet = choose_foot_joints(clips.names, clips.parents, clips.clips, foot_kind, foot_joints)
        except ValueError as error:
            raise AnalysisInputError(f"system {system!r}: {error}") from None
        same_rig = reference is not None and clips.names == reference.names
        if reference is not None and not same_rig:
            notes.append(f"No Fréchet distance for {system}: its joints are not {natural}'s.")
        for k, clip in enumerate(clips.clips):
            values = {"foot_sliding": lower_foot_speed([clip], clips.fps, feet),
                      "joint_acceleration": mean_joint_acceleration([clip], clips.fps)}
            if clips.offsets is not None:
                values["bone_length_rmse"] = bone_length_rmse([clip], clips.parents, clips.offsets)
            followed = clips.followed[k] if k < len(clips.followed) else None
            if followed is not None:
                position, heading = path_errors(followed)
                values["path_position_error"], values["path_heading_error"] = position.mean(), heading.mean()
            if same_rig and len(clip) >= 2:
                values["frechet_to_natural"] = frechet_distance(pose_features(clip, clips.parents), natural_features)
            stimulus = clip_stimulus(clips.source(k))
            rows += [{"system": system, "stimulus": stimulus, "metric": m, "value": float(v)}
                     for m, v in values.items()]
    return pd.DataFrame(rows, columns=["system", "stimulus", "metric", "value"]), notes


def metric_agreement(metrics: pd.DataFrame, ratings: pd.DataFrame, resamples: int = RESAMPLES, seed: int = 0,
                     confidence: float = 0.95) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Each metric's Kendall tau with the systems' mean ratings (bootstrap interval over
    participants and clips) and with the clips' mean ratings.

    ``metrics``: system, stimulus, metric, value (`clip_metrics`); ``ratings``: the kept
    ratings (participant, system, stimulus, value). Returns (agreement: ``AGREEMENT_COLUMNS``;
    per system: system, metric, metric_mean, rating_mean; notes).
    """
    ratings = by_clip_name(ratings)
    notes, rows, systems_rows = [], [], []
    tail = (1 - confidence) / 2 * 100
    clip_ratings = ratings.groupby(["system", "stimulus"])["value"].mean().rename("rating")
    for metric, values in metrics[np.isfinite(metrics["value"])].groupby("metric", sort=True):
        rated = ratings[ratings["system"].isin(set(values["system"]))]
        systems = sorted(set(rated["system"]))
        if len(systems) < MIN_POINTS:
            notes.append(f"No agreement for {metric}: {len(systems)} system(s) have both the metric and ratings "
                         f"({MIN_POINTS} or more needed).")
            continue
        values = values[values["system"].isin(systems)]
        metric_mean = values.groupby("system")["value"].mean()[systems]
        rating_mean = rated.groupby("system")["value"].mean()[systems]
        tau = float(kendall_tau_rows(metric_mean.to_numpy()[None], rating_mean.to_numpy()[None])[0])
        if not np.isfinite(tau):
            notes.append(f"No agreement for {metric}: the metric or the mean rating is the same for every system.")
            continue
        draws = _bootstrap_taus(values, rated, systems, resamples, seed)
        low, high = np.percentile(draws, [tail, 100 - tail]) if len(draws) else (np.nan, np.nan)
        by_clip = values.join(clip_ratings, on=["system", "stimulus"], how="inner")
        clip_tau, clip_p = (sps.kendalltau(by_clip["value"], by_clip["rating"]) if len(by_clip) >= MIN_POINTS
                            else (np.nan, np.nan))
        if len(by_clip) < MIN_POINTS:
            notes.append(f"No per-clip correlation for {metric}: {len(by_clip)} clip(s) are named in both the "
                         "motion and the ratings (a clip's stimulus is its file's stem).")
        participants = rated["participant"].nunique()
        if participants < INTERVAL_WARNING_PARTICIPANTS:
            notes.append(f"Agreement of {metric}: its interval comes from {participants} participants, fewer than "
                         f"{INTERVAL_WARNING_PARTICIPANTS}; read it as rough (few_participants in the table).")
        rows.append({"metric": metric, "tau": tau,
                     "ci_low": low, "ci_high": high, "n_systems": len(systems), "participants": participants,
                     "few_participants": participants < INTERVAL_WARNING_PARTICIPANTS, "resamples_used": len(draws),
                     "clip_tau": float(clip_tau), "clip_p": float(clip_p), "n_clips": len(by_clip)})
        systems_rows.append(pd.DataFrame({"system": systems, "metric": metric, "metric_mean": metric_mean.to_numpy(),
                                          "rating_mean": rating_mean.to_numpy()}))
    per_system = (pd.concat(systems_rows, ignore_index=True) if systems_rows
                  else pd.DataFrame(columns=["system", "metric", "metric_mean", "rating_mean"]))
    return pd.DataFrame(rows, columns=AGREEMENT_COLUMNS), per_system, notes


def by_clip_name(ratings: pd.DataFrame) -> pd.DataFrame:
    """The ratings with each clip named as the motion names it: its ``clip`` column (the
    study app's export, whose ``stimulus`` is an opaque token) where that is given."""
    if "clip" not in ratings.columns:
        return ratings
    named = ratings["clip"].fillna("").astype(str)
    return ratings.assign(stimulus=ratings["stimulus"].where(named == "", named))


def agreement_text(agreement: pd.DataFrame) -> str:
    """A paragraph: each metric's tau over systems with its interval, and per clip."""
    listed = "; ".join(
        f"{r.metric} {r.tau:.2f} [{r.ci_low:.2f}, {r.ci_high:.2f}] over {r.n_systems} systems"
        + (f" (rough: {r.participants} participants)" if r.few_participants else "")
        + (f", {r.clip_tau:.2f} over {r.n_clips} clips" if r.n_clips >= MIN_POINTS else "")
        for r in agreement.itertuples(index=False))
    return ("**Objective metrics against the raters.** Kendall's tau of each metric's system means with the "
            "systems' mean ratings, with 95 % bootstrap intervals over participants and clips, and of each clip's "
            f"metric with its mean rating (lower is better for every metric, so agreement is negative): {listed}.")


def kendall_tau_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Kendall's tau-b of every row pair of two (rows, n) arrays at once (NaN where either
    row is constant): the sum of sign(x_i - x_j) sign(y_i - y_j) over the pairs i < j over
    the square root of the untied pairs' counts in x and in y."""
    first, second = np.triu_indices(x.shape[1], 1)
    sx, sy = np.sign(x[:, first] - x[:, second]), np.sign(y[:, first] - y[:, second])
    with np.errstate(invalid="ignore", divide="ignore"):
        return (sx * sy).sum(axis=1) / np.sqrt((sx**2).sum(axis=1) * (sy**2).sum(axis=1))


def _bootstrap_taus(values: pd.DataFrame, rated: pd.DataFrame, systems: list[str], resamples: int,
                    seed: int) -> np.ndarray:
    """Kendall's tau of resampled system means: participants drawn with replacement and,
    within each system, clips; a resample in which a system has no rating left is skipped.
    Resamples are drawn in chunks, each a few matrix products over the (participant, clip)
    cells of the ratings."""
    clips = pd.MultiIndex.from_frame(pd.concat([values[["system", "stimulus"]], rated[["system", "stimulus"]]])
                                     ).unique()
    system_of_clip = pd.Index(systems).get_indexer(clips.get_level_values(0))
    clips_of_system = [np.flatnonzero(system_of_clip == s) for s in range(len(systems))]
    in_system = np.eye(len(systems))
    clip_of_value = clips.get_indexer(pd.MultiIndex.from_frame(values[["system", "stimulus"]]))
    value_system, value = in_system[system_of_clip[clip_of_value]], values["value"].to_numpy(dtype=np.float64)
    participant, participants = pd.factorize(rated["participant"])
    cells = pd.DataFrame({"participant": participant, "value": rated["value"].to_numpy(dtype=np.float64),
                          "clip": clips.get_indexer(pd.MultiIndex.from_frame(rated[["system", "stimulus"]]))}
                         ).groupby(["participant", "clip"])["value"].agg(["size", "sum"]).reset_index()
    cell_system = in_system[system_of_clip[cells["clip"].to_numpy()]]
    rng = np.random.default_rng(seed)
    taus = []
    for start in range(0, resamples, _CHUNK):
        size = min(_CHUNK, resamples - start)
        person_weight = rng.multinomial(len(participants), np.full(len(participants), 1 / len(participants)), size)
        clip_weight = np.zeros((size, len(clips)))
        for members in clips_of_system:
            clip_weight[:, members] = rng.multinomial(len(members), np.full(len(members), 1 / len(members)), size)
        weight = person_weight[:, cells["participant"].to_numpy()] * clip_weight[:, cells["clip"].to_numpy()]
        rating_total = (weight * cells["size"].to_numpy()) @ cell_system
        metric_total = clip_weight[:, clip_of_value] @ value_system
        usable = (rating_total > 0).all(axis=1) & (metric_total > 0).all(axis=1)
        scores = ((weight * cells["sum"].to_numpy()) @ cell_system)[usable] / rating_total[usable]
        metric = ((clip_weight[:, clip_of_value] * value) @ value_system)[usable] / metric_total[usable]
        tau = kendall_tau_rows(metric, scores)
        taus.append(tau[np.isfinite(tau)])
    return np.concatenate(taus) if taus else np.empty(0)
