"""Footstep analysis of MoGlow Sec. 5.3 (Table 3, Fig. 5): how cleanly feet plant.

A foot is in contact with the ground while the horizontal speed of its heel (bipeds) or
toe (quadrupeds) joint is below a tolerance v_tol. A footstep is a run of contact at
least ``min_contact_s`` long that starts inside its clip: at tolerances near the noise
floor a planted heel's speed flickers around v_tol, and without a minimum length each
flicker would count as a step; a contact already under way at a clip's first frame began
before the clip and is not a footstep of it.

- f_est(v_tol): footsteps per second over all clips of a system, for a sweep of
  tolerances (the Fig. 5 curve). It rises as tolerances admit more real contacts and
  saturates at the step rate; sliding feet need a larger tolerance to get there.
  A footstep is counted once, at its touchdown.
- v_tol^(95): the first tolerance of the sweep where f_est reaches 95 % of its maximum
  (sweep steps of 1.0 cm/s for humans): lower means crisper foot plants.
- Step durations: the times between consecutive footfalls (starts of footsteps of either
  foot) within a clip, at v_tol^(95).

Clip edges still cost some precision on short clips: a touchdown in a clip's last
min_contact_s is counted only at tolerances high enough to detect it a few frames
earlier. Pooling many clips per system keeps this well under the 5 % of v_tol^(95).

Speeds are finite differences of positions in cm (y up), so the curves are in cm/s.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.errors import AnalysisInputError

HUMAN_TOLERANCES = np.arange(0.0, 101.0, 1.0)  # cm/s
DEFAULT_MIN_CONTACT_S = 0.1


class FootSpeeds:
    """Horizontal foot speeds of many clips laid end to end, one NaN row between clips.

    The NaN rows compare False with any tolerance, so contact runs never join across
    clips and every clip's runs can be found in one array operation.
    """

    def __init__(self, clips: Sequence[np.ndarray], fps: float, foot_indices: Sequence[int]):
        if fps <= 0:
            raise AnalysisInputError(f"fps must be positive, got {fps}")
        if len(clips) == 0:
            raise AnalysisInputError("no clips given")
        parts, starts, total_frames = [], [], 0
        for clip in clips:
            clip = np.asarray(clip, dtype=np.float64)
            if clip.ndim != 3 or clip.shape[-1] != 3 or len(clip) < 2:
                raise AnalysisInputError(
                    f"each clip must be (frames >= 2, joints, 3) positions, got {clip.shape}"
                )
            feet = clip[:, list(foot_indices)][:, :, [0, 2]]  # x and z: y is up
            speed = np.linalg.norm(np.diff(feet, axis=0), axis=-1) * fps
            starts.append(sum(len(p) for p in parts))
            parts += [speed, np.full((1, speed.shape[1]), np.nan)]
            total_frames += len(clip)
        self.speed = np.concatenate(parts)  # (samples, feet)
        self.clip_starts = np.asarray(starts)  # first sample of each clip
        self.duration_s = total_frames / fps
        self.fps = fps

    def footstep_starts(self, v_tol: np.ndarray, min_samples: int) -> np.ndarray:
        """Boolean (tolerances, samples, feet): a footstep starts at this sample.

        A footstep is a contact run of at least ``min_samples`` that starts inside its
        clip (a run already under way at the first sample began before the clip).
        """
        contact = self.speed[None] < np.asarray(v_tol, dtype=np.float64)[:, None, None]
        padded = np.concatenate([np.zeros_like(contact[:, :1]), contact], axis=1)
        run = np.cumsum(padded, axis=1, dtype=np.int32)
        n = contact.shape[1]
        ends = np.minimum(np.arange(n) + min_samples, n)
        # runs cannot cross the NaN separators, so a window reaching into the next clip
        # simply falls short of min_samples
        lasting = (run[:, ends] - run[:, :n]) == min_samples
        begins = contact & ~padded[:, :-1]
        begins[:, self.clip_starts] = False
        return begins & lasting
def _min_samples(min_contact_s: float, fps: float) -> int:
    return max(1, int(round(min_contact_s * fps)))


def footstep_tolerance_curve(clips: Sequence[np.ndarray], fps: float, foot_indices: Sequence[int],
                             tolerances: np.ndarray = HUMAN_TOLERANCES,
                             min_contact_s: float = DEFAULT_MIN_CONTACT_S) -> pd.DataFrame:
    """f_est(v_tol) over a sweep of tolerances. Columns: v_tol, footsteps, f_est."""
    speeds = FootSpeeds(clips, fps, foot_indices)
    starts = speeds.footstep_starts(tolerances, _min_samples(min_contact_s, fps))
    steps = starts.sum(axis=(1, 2))
    return pd.DataFrame({"v_tol": np.asarray(tolerances, dtype=np.float64),
                         "footsteps": steps, "f_est": steps / speeds.duration_s})


def v_tol_95(curve: pd.DataFrame, level: float = 0.95) -> float:
    """The first tolerance where f_est reaches ``level`` of its maximum (NaN: no steps)."""
    peak = curve["f_est"].max()
    if not peak > 0:
        return float("nan")
    return float(curve["v_tol"].to_numpy()[np.argmax(curve["f_est"].to_numpy() >= level * peak)])


def step_durations(clips: Sequence[np.ndarray], fps: float, foot_indices: Sequence[int],
                   v_tol: float, min_contact_s: float = DEFAULT_MIN_CONTACT_S) -> np.ndarray:
    """Seconds between consecutive footfalls (either foot) within each clip, all clips."""
    speeds = FootSpeeds(clips, fps, foot_indices)
    starts = speeds.footstep_starts(np.array([v_tol]), _min_samples(min_contact_s, fps))[0]
    sample = np.nonzero(starts.any(axis=1))[0]
    clip = np.searchsorted(speeds.clip_starts, sample, side="right") - 1
    same_clip = clip[1:] == clip[:-1]
    return (np.diff(sample) / fps)[same_clip]


def footstep_summary(clips: Sequence[np.ndarray], fps: float, foot_indices: Sequence[int],
                     tolerances: np.ndarray = HUMAN_TOLERANCES,
                     min_contact_s: float = DEFAULT_MIN_CONTACT_S) -> tuple[dict, pd.DataFrame]:
    """The Table 3 footstep entries of one system and its Fig. 5 curve.

    Returns ({v_tol_95, steps_per_s, step_duration_mean, step_duration_sd,
    n_step_durations}, curve); the values are NaN when no footsteps were found, which the
    report states in a note.
    """
    curve = footstep_tolerance_curve(clips, fps, foot_indices, tolerances, min_contact_s)
    v95 = v_tol_95(curve)
    durations = (step_durations(clips, fps, foot_indices, v95, min_contact_s)
                 if np.isfinite(v95) else np.empty(0))
    return {
        "v_tol_95": v95,
        "steps_per_s": float(curve["f_est"].max()),
        "step_duration_mean": float(durations.mean()) if len(durations) else float("nan"),
        "step_duration_sd": float(durations.std(ddof=1)) if len(durations) > 1 else float("nan"),
        "n_step_durations": int(len(durations)),
    }, curve
