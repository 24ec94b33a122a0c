"""The feet of a figure and how fast the weight-bearing one moves.

The foot joints are found by name (heels, else ankles or feet; or toes), else as the
rig's two lowest end joints; ``lower_foot_speed`` is the horizontal speed of whichever
foot is lowest in each frame (the one bearing weight): a planted foot hardly moves
(natural walking: about 13 cm/s), a figure that glides instead of stepping moves it at
the body's speed. ``analysis`` reports it beside the footstep metrics, and
``generation.sliding`` measures where a model's sliding arises with it.

Positions are (frames, joints, 3) in centimetres with y up, so speeds are in cm/s.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

_FOOT_PATTERNS = {
    "heel": (r"heel", r"foot|ankle"),  # a heel joint if there is one, else the ankle
    "toe": (r"toe",),
}


def find_foot_joints(names: Sequence[str], kind: str = "heel") -> list[str]:
    """The foot joints of a skeleton chosen by name: heels (or ankles/feet) or toes.

    Matching is case-insensitive; for ``kind="heel"`` a joint named like ``*heel*`` is
    preferred, then ``*foot*`` / ``*ankle*``, never one that also mentions toes. Raises
    ValueError when fewer than two joints match; name them explicitly then.
    """
    if kind not in _FOOT_PATTERNS:
        raise ValueError(f"foot kind must be one of {sorted(_FOOT_PATTERNS)}, got {kind!r}")
    for pattern in _FOOT_PATTERNS[kind]:
        found = [n for n in names if re.search(pattern, n, re.I)
                 and (kind == "toe" or not re.search(r"toe", n, re.I))]
        if len(found) >= 2:
            return found
    raise ValueError(
        f"cannot find two {kind} joints by name among {', '.join(names)}; pass the foot "
        "joints explicitly (foot_joints=[...] or --foot-joints)"
    )


def feet_of_rig(parents: Sequence[int], clips: Sequence[np.ndarray]) -> list[int]:
    """The two end effectors (joints without children) lowest on average over the clips:
    the feet of a rig whose joint names say nothing (toes, where a rig has them)."""
    parents = np.asarray(parents)
    ends = [j for j in range(len(parents)) if j not in set(parents.tolist())]
    if len(ends) < 2:
        raise ValueError("cannot find the feet: the skeleton has fewer than two end joints; "
                         "pass the foot joints explicitly (--foot-joints)")
    height = np.mean([np.asarray(clip)[:, ends, 1].mean(axis=0) for clip in clips], axis=0)
    return sorted(ends[i] for i in np.argsort(height, kind="stable")[:2])


def choose_foot_joints(names: Sequence[str], parents: Sequence[int], clips: Sequence[np.ndarray],
                       kind: str = "heel", given: Sequence[str] | None = None) -> list[int]:
    """The indices of the foot joints: ``given`` by name, else found by name
    (``find_foot_joints``), else the rig's lowest end effectors (``feet_of_rig``)."""
    if given:
        unknown = [f for f in given if f not in names]
        if unknown:
            raise ValueError(f"no joint(s) {', '.join(unknown)} in the skeleton ({', '.join(names)})")
        return [list(names).index(f) for f in given]
    try:
        return [list(names).index(f) for f in find_foot_joints(names, kind)]
    except ValueError:
        return feet_of_rig(parents, clips)


def lower_foot_speed(clips: Sequence[np.ndarray], fps: float, foot_indices: Sequence[int]) -> float:
    """Mean horizontal speed (cm/s, y up) over the last frame of the lowest foot joint in each frame."""
    speeds = []
    for clip in clips:
        if len(clip) < 2:
            continue
        feet = clip[:, list(foot_indices)]
        lowest = feet[1:, :, 1].argmin(axis=1)  # the foot nearest the floor at the end of each step
        step = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1)  # (frames-1, feet)
        speeds.append(step[np.arange(len(step)), lowest] * fps)
    return float(np.concatenate(speeds).mean()) if speeds else float("nan")
