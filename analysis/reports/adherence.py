"""Control adherence: how closely motion does what its control asked.

For path controls, a clip's root is compared with the control's path frame by frame
(both read from its motion file, `analysis.motion.motion_io`): the *position error* is the
distance on the floor between where the root is and where the path says it should be
by then (cm), the *heading error* the angle between the root's facing and the facing
the path asks for (degrees, 0 to 180). Per system: their means over every frame of
every clip, their means at the clips' last frames (where drift has added up), and the
mean over clips at each moment (a curve over time).

For label controls, adherence is how often an attribute classifier recognises the
action and the style a clip was asked for (HVRNN's classifiers, run by ``python -m
generation hvrnn-eval``): the accuracy per set of the outputs file, with Wilson
intervals.

`adherence_correlation` relates either to the mean appropriateness scores of the same
systems (`analysis.stats.matching`): a metric that tracks what participants see
correlates negatively (errors) or positively (accuracies) with the scores.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.reports.attribute_scores import ClassifierOutputs
from analysis.stats.correlation import subjective_objective_correlation
from analysis.motion.motion_io import FollowedPath, SystemClips
from analysis.stats.preferences import wilson_interval

PATH_COLUMNS = ("position_error_mean", "position_error_end", "heading_error_mean", "heading_error_end")
LABEL_COLUMNS = ("action_accuracy", "style_accuracy")


def path_errors(followed: FollowedPath) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the root's distance from the control's path (cm) and the difference of
    their facings (degrees, wrapped to 0..180)."""
    position = np.linalg.norm(followed.root_xz - followed.control_xz, axis=1)
    turn = np.angle(np.exp(1j * (followed.root_yaw - followed.control_yaw)))
    return position, np.degrees(np.abs(turn))


def path_adherence(motion: dict[str, SystemClips]) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Position and heading errors of every system whose clips carry a control path.

    Returns (table: system, n_clips and the ``PATH_COLUMNS``; curves: system, time_s,
    position_error, heading_error, n_clips (the clips as long as that moment), means over
    those clips; notes on clips without a control).
    """
    rows, curves, notes = [], [], []
    for system, clips in sorted(motion.items()):
        measured = [path_errors(f) for f in clips.followed if f is not None]
        if len(measured) < len(clips.clips):
            notes.append(f"{system}: {len(clips.clips) - len(measured)} of {len(clips.clips)} clips carry no control "
                         "path (control_path, control_yaw, root_path, root_yaw); "
                         + ("control adherence from the others." if measured else "no control adherence."))
        if not measured:
            continue
        rows.append({"system": system, "n_clips": len(measured),
                     "position_error_mean": float(np.concatenate([p for p, _ in measured]).mean()),
                     "position_error_end": float(np.mean([p[-1] for p, _ in measured])),
                     "heading_error_mean": float(np.concatenate([h for _, h in measured]).mean()),
                     "heading_error_end": float(np.mean([h[-1] for _, h in measured]))})
        longest = max(len(p) for p, _ in measured)
        stacked = np.full((2, len(measured), longest), np.nan)  # clips of different lengths, NaN after their end
        for k, (position, heading) in enumerate(measured):
            stacked[:, k, :len(position)] = position, heading
        curves.append(pd.DataFrame({"system": system, "time_s": np.arange(longest) / clips.fps,
                                    "position_error": np.nanmean(stacked[0], axis=0),
                                    "heading_error": np.nanmean(stacked[1], axis=0),
                                    "n_clips": np.isfinite(stacked[0]).sum(axis=0)}))
    table = pd.DataFrame(rows, columns=["system", "n_clips", *PATH_COLUMNS])
    curve_table = (pd.concat(curves, ignore_index=True) if curves else
                   pd.DataFrame(columns=["system", "time_s", "position_error", "heading_error", "n_clips"]))
    return table, curve_table, notes


def label_adherence(outputs: ClassifierOutputs, confidence: float = 0.95) -> pd.DataFrame:
    """Per set of sequences (a system, the real takes, the reference): n and, for the
    action and the style, the share the classifier recognised (``*_accuracy``) with its
    Wilson interval (``*_ci_low``, ``*_ci_high``)."""
    rows = []
    for name, arrays in outputs.sets.items():
        row = {"system": name, "n": len(arrays["action"])}
        for kind in ("action", "style"):
            right = int((arrays[f"{kind}_probabilities"].argmax(axis=1) == arrays[kind]).sum())
            low, high = wilson_interval(right, row["n"], confidence)
            row.update({f"{kind}_accuracy": right / row["n"], f"{kind}_ci_low": float(low),
                        f"{kind}_ci_high": float(high)})
        rows.append(row)
    return pd.DataFrame(rows)


def adherence_correlation(mean_scores: pd.Series, adherence: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Pearson r across systems between the mean appropriateness score (``mean_scores``,
    indexed by system) and each adherence metric (``adherence``: system and the
    ``PATH_COLUMNS`` or ``LABEL_COLUMNS``); (table: metric, n_systems, r, p; notes)."""
    metrics = [c for c in (*PATH_COLUMNS, *LABEL_COLUMNS) if c in adherence.columns]
    return subjective_objective_correlation(mean_scores, adherence.set_index("system")[metrics])
