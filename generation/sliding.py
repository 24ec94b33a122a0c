"""Where a MoGlow's foot sliding arises, measured on held-out takes.

The weight-bearing foot's speed (``measures.feet.lower_foot_speed``) of versions
of each take's motion, all on the take's own control and all measured over the same
frames (from ``SETTLE_SECONDS`` on), each version a step further from the take:

* natural: the take itself;
* one frame ahead, T=0: each frame predicted from the take's true past poses (teacher
  forcing, ``MoGlow.generate(true_past=...)``) and placed on the take's root, its step
  measured from the take's previous frame: what one prediction adds;
* free-running from the take's first τ poses, at T=0 and T=1: what compounding the
  predictions and drawing the noise add;
* from the mean pose, T=1, as the authors' code samples a test take's control (and
  ``sample -c held-out --lead-in``, its warm-up running on the take's own start);
* from the mean pose after a warm-up that holds the first control frame, T=1, as
  ``Generator.sample`` does for a control without a lead-in (studies' held-out controls).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import torch

from measures.feet import lower_foot_speed

from .control import PathControl
from .generator import Generator
from .motion.features import decode_positions

SETTLE_SECONDS = 1.0  # frames before this are the context or the settling from the mean pose, in every version
CONDITIONS = ("natural", "one frame ahead, T=0", "from the take's poses, T=0", "from the take's poses, T=1",
              "from the mean pose, T=1", "mean pose + warm-up, T=1")


def sliding_ladder(generator: Generator, takes: Sequence[tuple[np.ndarray, np.ndarray]],
                   foot_indices: Sequence[int], samples: int = 8, seed: int = 1) -> pd.DataFrame:
    """One row per condition (``CONDITIONS``): columns condition, lower_foot_speed (cm/s),
    clips. ``takes`` are (pose, control) feature arrays of held-out takes, each more
    than ``SETTLE_SECONDS`` long; every T=1 condition draws ``samples`` per take."""
    if samples < 1:
        raise ValueError(f"samples must be at least 1, not {samples}")
    if not takes:
        raise ValueError("no held-out takes to measure")
    model, fps = generator.model, generator.fps
    tau, settle = model.context_frames, max(int(round(SETTLE_SECONDS * fps)), model.context_frames)
    clips: dict[str, list[np.ndarray]] = {condition: [] for condition in CONDITIONS}
    for pose, control in takes:
        if len(pose) < settle + 2:
            raise ValueError(f"a take of {len(pose)} frames is too short: the measurement starts at frame {settle}")
        world = decode_positions(pose, control, fps)
        clips["natural"].append(world[settle:])
        control_in = torch.as_tensor(generator.control_stats.apply(generator.control_layout(control, fps))[None])
        past = torch.as_tensor(generator.pose_stats.apply(pose)[None])

        predicted = _positions(generator, model.generate(control_in, None, 0.0, true_past=past)[0], control)
        # Each predicted frame after the take's own previous frame: a two-frame clip per frame.
        clips["one frame ahead, T=0"] += [np.stack([world[t - 1], predicted[t]]) for t in range(settle, len(pose))]

        for condition, temperature, context in (("from the take's poses, T=0", 0.0, past[:, :tau]),
                                                ("from the take's poses, T=1", 1.0, past[:, :tau]),
                                                ("from the mean pose, T=1", 1.0, None)):
            n = samples if temperature > 0 else 1
            noise = torch.Generator(device=generator.device).manual_seed(seed)  # the noise is drawn where the model runs
            sampled = model.generate(control_in.expand(n, -1, -1), None if context is None else context.expand(n, -1, -1),
                                     temperature, noise)
            clips[condition] += [_positions(generator, s, control)[settle:] for s in sampled]
        warmed = generator.sample(PathControl(control, fps), n=samples, seed=seed, precision="float32")
        clips["mean pose + warm-up, T=1"] += [motion.positions[settle:] for motion in warmed]
    counts = {c: len(takes) * (samples if c.endswith("T=1") else 1) for c in CONDITIONS}
    return pd.DataFrame([{"condition": c, "lower_foot_speed": lower_foot_speed(clips[c], fps, foot_indices),
                          "clips": counts[c]} for c in CONDITIONS])


def _positions(generator: Generator, standardised_pose: torch.Tensor, control: np.ndarray) -> np.ndarray:
    """World joint positions (frames, joints, 3) of a standardised pose sequence on the take's root."""
    return decode_positions(generator.pose_stats.invert(standardised_pose.double().cpu().numpy()), control,
                            generator.fps)
