"""The objective metrics of all systems at once: MoGlow Table 3 and the Fig. 5 curves,
with jitter (``analysis.motion.smoothness``) and foot sliding (``measures.feet``) beside them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.motion.bones import bone_length_rmse
from analysis.errors import AnalysisInputError
from analysis.motion.footsteps import DEFAULT_MIN_CONTACT_S, HUMAN_TOLERANCES, footstep_summary
from analysis.motion.motion_io import SystemClips
from analysis.motion.smoothness import mean_joint_acceleration
from measures.feet import choose_foot_joints, lower_foot_speed

METRIC_COLUMNS = ("v_tol_95", "step_duration_mean", "step_duration_sd", "bone_length_rmse", "joint_acceleration",
                  "lower_foot_speed")


def objective_metrics(motion: dict[str, SystemClips], foot_joints: Sequence[str] | None = None,
                      foot_kind: str = "heel", tolerances: np.ndarray = HUMAN_TOLERANCES,
                      min_contact_s: float = DEFAULT_MIN_CONTACT_S
                      ) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Footstep, bone-length, jitter and foot-sliding metrics per system.

    Returns (table with columns system, n_clips, steps_per_s, v_tol_95,
    step_duration_mean, step_duration_sd, bone_length_rmse, joint_acceleration,
    lower_foot_speed; curves with columns system, v_tol, footsteps, f_est; notes on
    anything not computed). Foot joints are found by name or from the rig (`choose_foot_joints`)
    unless given.
    """
    rows, curves, notes = [], [], []
    for system, clips in sorted(motion.items()):
        try:
            foot_indices = choose_foot_joints(clips.names, clips.parents, clips.clips, foot_kind, foot_joints)
        except ValueError as error:
            raise AnalysisInputError(f"system {system!r}: {error}") from None
        summary, curve = footstep_summary(clips.clips, clips.fps, foot_indices, tolerances, min_contact_s)
        if not np.isfinite(summary["v_tol_95"]):
            notes.append(f"{system}: no footsteps at any tolerance up to {tolerances[-1]:g} cm/s; "
                         "v_tol^(95) and step durations not computed.")
        elif summary["n_step_durations"] < 2:
            notes.append(f"{system}: fewer than two step durations; their spread not computed.")
        if clips.offsets is None:
            rmse = float("nan")
            notes.append(f"{system}: no skeleton offsets in the motion files; bone-length "
                         "error not computed.")
        else:
            rmse = bone_length_rmse(clips.clips, clips.parents, clips.offsets)
        rows.append({"system": system, "n_clips": len(clips.clips), **summary, "bone_length_rmse": rmse,
                     "joint_acceleration": mean_joint_acceleration(clips.clips, clips.fps),
                     "lower_foot_speed": lower_foot_speed(clips.clips, clips.fps, foot_indices)})
        curves.append(curve.assign(system=system))
    table = pd.DataFrame(rows).drop(columns="n_step_durations")
    curve_table = pd.concat(curves, ignore_index=True)[["system", "v_tol", "footsteps", "f_est"]]
    return table, curve_table, notes
