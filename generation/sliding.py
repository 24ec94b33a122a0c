"""Where a MoGlow's foot sliding arises, measured on held-out takes.

The weight-bearing foot's speed (``analysis.smoothness.lower_foot_speed``) of four
versions of each take's motion, all on the take's own control:

* natural: the take itself;
* one frame ahead, T=0: each frame predicted from the take's true past poses (teacher
  forcing, ``MoGlow.generate(true_past=...)``) and placed on the take's root, so its step
  is measured from the take's previous frame: what one prediction adds;
* free-running, T=0 and T=1: samples that start from the take's first τ poses and
  then see only their own frames: what compounding the predictions and sampling the
  noise add.

A start from the mean pose and synthetic control (the tables of
``scripts/moglow-fidelity.sh``) add the rest.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import torch

from analysis.smoothness import lower_foot_speed

from .generator import Generator
from .motion.features import decode_positions

CONDITIONS = ("natural", "one frame ahead, T=0", "free-running, T=0", "free-running, T=1")


def sliding_ladder(generator: Generator, takes: Sequence[tuple[np.ndarray, np.ndarray]],
                   foot_indices: Sequence[int], samples: int = 8, seed: int = 1) -> pd.DataFrame:
    """One row per condition (``CONDITIONS``): columns condition, lower_foot_speed (cm/s),
    clips. ``takes`` are (pose, control) feature arrays of held-out takes, each longer
    than τ frames; the free-running T=1 condition draws ``samples`` per take."""
    if samples < 1:
        raise ValueError(f"samples must be at least 1, not {samples}")
    if not takes:
        raise ValueError("no held-out takes to measure")
    tau, fps = generator.model.context_frames, generator.fps
    clips: dict[str, list[np.ndarray]] = {condition: [] for condition in CONDITIONS}
    for pose, control in takes:
        if len(pose) <= tau:
            raise ValueError(f"a take of {len(pose)} frames is too short: the model needs more than {tau}")
        world = decode_positions(pose, control, fps)
        clips["natural"].append(world[tau:])
        control_in = torch.as_tensor(generator.control_stats.apply(generator.control_layout(control, fps))[None])
        past = torch.as_tensor(generator.pose_stats.apply(pose)[None])
        predicted = _positions(generator, generator.model.generate(control_in, None, 0.0, true_past=past)[0], control)
        # Each predicted frame after the take's own previous frame: a two-frame clip per frame.
        clips["one frame ahead, T=0"] += [np.stack([world[t - 1], predicted[t]]) for t in range(tau, len(pose))]
        for condition, temperature, n in (("free-running, T=0", 0.0, 1), ("free-running, T=1", 1.0, samples)):
            free = generator.model.generate(control_in.expand(n, -1, -1), past[:, :tau].expand(n, -1, -1), temperature,
                                            torch.Generator().manual_seed(seed))
            clips[condition] += [_positions(generator, sample, control)[tau:] for sample in free]
    return pd.DataFrame([{"condition": condition, "lower_foot_speed": lower_foot_speed(clips[condition], fps, foot_indices),
                          "clips": len(takes) * (samples if condition == "free-running, T=1" else 1)}
                         for condition in CONDITIONS])


def _positions(generator: Generator, standardised_pose: torch.Tensor, control: np.ndarray) -> np.ndarray:
    """World joint positions (frames, joints, 3) of a standardised pose sequence on the take's root."""
    return decode_positions(generator.pose_stats.invert(standardised_pose.double().cpu().numpy()), control,
                            generator.fps)
