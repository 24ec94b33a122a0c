"""Sampling motion from a trained model: DESIGN.md's one interface for every model.

    generator = Generator.load("moglow-cpu.safetensors")
    motions = generator.sample(preset_path("walk-circle"), n=4, seed=1, temperature=1.0)

The generator owns what the models do not: standardisation, the seed context, the
optional warm-up second that MoGlow generates and discards, and turning features back
into a ``Motion`` placed in the world. Path models (MoGlow and its baselines) follow a
``PathControl``; attribute models (HVRNN, ERD, QuaterNet) take an ``AttributeControl``
and return joint-angle features, decoded onto the skeleton:

    Generator.load("hvrnn-cpu.safetensors").sample(AttributeControl("walk", "happy", 120, 30.0), n=4, seed=1)

Many controls, each with its own seed, in one batch (a study's worker does this):
``sample_batch(controls, seeds)`` gives each control the motion ``sample(control, n=1,
seed=its seed)`` gives.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence

import numpy as np
import torch

from .checkpoint import CheckpointMeta, load_checkpoint
from .control import AttributeControl, Control, PathControl
from .motion.dataset import Standardizer
from .motion.features import AngleFeatureSpec, decode_angles, decode_positions
from .motion.types import Motion, Skeleton
from .stylegestures import CONTROL_LAYOUT, stylegestures_control
from .models.attribute import AttributeModel
from .models.motion_model import MotionModel
from .models.noise import RowGenerators
from .models.path import PathModel
from .models.precision import auto_precision


# Bounds on a request, checked before anything is allocated: a warm-up is a second or
# two (MoGlow's paper uses one), and a batch of samples fits in memory.
MAX_WARMUP_SECONDS = 60.0
MAX_SAMPLES = 10_000


def check_request(n: int, temperature: float, warmup_seconds: float | None) -> None:
    """Refuse a sampling request no model can honour, naming the argument."""
    if not 1 <= n <= MAX_SAMPLES:
        raise ValueError(f"n must be at least 1 and at most {MAX_SAMPLES:,}, got {n}")
    if not (math.isfinite(temperature) and temperature >= 0):
        raise ValueError(f"temperature must be a finite number of at least 0, got {temperature}")
    if warmup_seconds is not None and not 0 <= warmup_seconds <= MAX_WARMUP_SECONDS:
        raise ValueError(f"warmup_seconds must be between 0 and {MAX_WARMUP_SECONDS:g}, got {warmup_seconds}")


def _own_layout(velocities: np.ndarray, fps: float) -> np.ndarray:
    return velocities


# How a checkpoint's model reads the path control (features["control_layout"]): ours
# (forward, sideways, yaw velocity) unless it was imported from the authors' code.
CONTROL_LAYOUTS = {None: _own_layout, CONTROL_LAYOUT: stylegestures_control}


def control_layout(name: str | None) -> Callable[[np.ndarray, float], np.ndarray]:
    if name not in CONTROL_LAYOUTS:
        raise ValueError(f"unknown control_layout {name!r} in the checkpoint's features")
    return CONTROL_LAYOUTS[name]


class Generator:
    """A trained model with everything needed to turn control into motion."""

    def __init__(self, model: MotionModel, meta: CheckpointMeta, device: str | torch.device = "cpu") -> None:
        self.model, self.meta, self.device = model.to(device).eval(), meta, torch.device(device)
        self.skeleton = Skeleton.from_dict(meta.skeleton)
        self.fps = float(meta.features["dataset_options"]["fps"])
        self.pose_stats = Standardizer.from_dict(meta.stats["pose"])
        self.attributes = isinstance(model, AttributeModel)
        if self.attributes:
            self.angle_spec = AngleFeatureSpec.from_dict(meta.features["angle_spec"])
        else:
            self.control_stats = Standardizer.from_dict(meta.stats["control"])
            self.control_layout = control_layout(meta.features.get("control_layout"))

    @classmethod
    def load(cls, path: str | os.PathLike, device: str | torch.device = "cpu") -> "Generator":
        model, meta = load_checkpoint(path, device)
        return cls(model, meta, device)

    def resolve_precision(self, precision: str = "auto") -> str:
        """The precision sampling multiplies in: ``precision`` itself, or for "auto" the
        one ``generation.models.precision.auto_precision`` picks for this model and device
        (bfloat16 on CPUs with bfloat16 units, float32 elsewhere)."""
        if precision == "auto":
            return auto_precision(self.device, self.model.precisions)
        self.model.check_precision(precision)
        return precision

    def check_control(self, control: Control) -> None:
        """Refuse a control this model cannot follow (ValueError naming what is wrong):
        the wrong kind of control, another frame rate, labels the model does not know."""
        if self.attributes:
            if not isinstance(control, AttributeControl):
                raise ValueError(f"a {self.meta.kind} model is controlled by action and style labels "
                                 f"(AttributeControl); got {type(control).__name__}")
            self.model.label_indices(control.action, control.style)
        elif not isinstance(self.model, PathModel):
            raise TypeError(f"a {self.meta.kind} model follows neither a path nor labels")
        elif not isinstance(control, PathControl):
            raise ValueError(f"a {self.meta.kind} model follows a path; got {type(control).__name__}")
        if abs(control.fps - self.fps) > 1e-6:
            raise ValueError(f"control is at {control.fps:g} fps but the model was trained at {self.fps:g} fps")

    def sample(
        self,
        control: Control,
        n: int = 1,
        seed: int = 0,
        temperature: float = 1.0,
        warmup_seconds: float | None = None,
        context: np.ndarray | None = None,
        precision: str = "auto",
    ) -> list[Motion]:
        """``n`` motions following ``control``; the same seed gives the same motions.

        ``warmup_seconds`` of motion are generated before the kept part and discarded
        (default: 1 s for autoregressive models, as in MoGlow, else 0), on the end of the
        control's lead-in where it has one, else holding its first frame. ``context``
        (context_frames, 3 × joints, in the root frame, cm) seeds autoregressive models;
        by default they start from the mean pose.
        Attribute models take an ``AttributeControl`` and neither of those two.
        ``precision`` is "auto" or one the model offers (``model.precisions``); see
        ``resolve_precision``.
        """
        precision = self.resolve_precision(precision)
        check_request(n, temperature, warmup_seconds)
        self.check_control(control)
        noise = torch.Generator(device=self.device).manual_seed(seed)
        return self._generate([control] * n, noise, temperature, warmup_seconds, context, precision)

    def sample_batch(
        self,
        controls: Sequence[Control],
        seeds: Sequence[int],
        temperature: float = 1.0,
        precision: str = "auto",
    ) -> list[Motion]:
        """One motion per control, the i-th drawn from ``seeds[i]``: each equals
        ``sample(controls[i], n=1, seed=seeds[i])`` (to float rounding), computed in as
        few model calls as the controls allow.

        Controls of one length share one call of the model. Controls of different
        lengths are not padded to one length: each row's noise is drawn in the shape of
        its own clip, and a padded clip would draw more and so differ from the clip
        sampled alone. A model that does not take a seed per row (``per_row_seeds``) is
        called once per control. The caller bounds the batch (the study's workers take
        STUDY_SAMPLE_BATCH controls at a time).
        """
        if len(controls) != len(seeds):
            raise ValueError(f"one seed per control: {len(controls)} controls, {len(seeds)} seeds")
        if not controls:
            return []
        precision = self.resolve_precision(precision)
        check_request(len(controls), temperature, None)
        for control in controls:
            self.check_control(control)
        if not self.model.per_row_seeds:
            return [self.sample(c, 1, s, temperature, precision=precision)[0] for c, s in zip(controls, seeds)]
        by_length: dict[int, list[int]] = {}
        for i, control in enumerate(controls):
            by_length.setdefault(control.n_frames, []).append(i)
        motions: list[Motion | None] = [None] * len(controls)
        for rows in by_length.values():
            noise = RowGenerators([seeds[i] for i in rows], self.device)
            for i, motion in zip(rows, self._generate([controls[i] for i in rows], noise, temperature, None, None,
                                                      precision)):
                motions[i] = motion
        return motions

    def _generate(self, controls: list[Control], noise: torch.Generator | RowGenerators, temperature: float,
                  warmup_seconds: float | None, context: np.ndarray | None, precision: str) -> list[Motion]:
        """One call of the model for checked controls of one length, a row each."""
        if self.attributes:
            return self._generate_attributes(controls, noise, temperature)
        model = self.model
        context_frames = model.context_frames
        if warmup_seconds is None:
            warmup_seconds = 1.0 if context_frames else 0.0
        warmup = max(int(round(warmup_seconds * self.fps)), context_frames)
        laid_out = {id(c): self.control_layout(np.concatenate([c.warmup(warmup), c.velocities]), self.fps)
                    for c in controls}  # by identity: ``sample`` passes one control n times
        c = torch.as_tensor(self.control_stats.apply(np.stack([laid_out[id(c)] for c in controls])),
                            dtype=torch.float32, device=self.device)

        seed_poses = None
        if context_frames:
            if context is None:
                context = np.repeat(self.pose_stats.mean[None], context_frames, axis=0)
            if np.shape(context) != (context_frames, model.pose_dim):
                raise ValueError(f"context must have shape ({context_frames}, {model.pose_dim}), got {np.shape(context)}")
            seed_poses = torch.as_tensor(self.pose_stats.apply(context), dtype=torch.float32, device=self.device)
            seed_poses = seed_poses.expand(len(controls), -1, -1).contiguous()

        with torch.inference_mode():
            poses = model.generate(c, seed_poses, temperature, noise, precision)
        poses = self.pose_stats.invert(poses[:, warmup:].double().cpu().numpy())
        return [
            Motion(decode_positions(p, control.velocities, self.fps), self.fps, self.skeleton)
            for p, control in zip(poses, controls)
        ]

    def _generate_attributes(self, controls: list[Control], noise: torch.Generator | RowGenerators,
                             temperature: float) -> list[Motion]:
        indices = [self.model.label_indices(c.action, c.style) for c in controls]
        labels = [torch.tensor(column, dtype=torch.long, device=self.device) for column in zip(*indices)]
        with torch.inference_mode():
            features = self.model.generate(*labels, controls[0].frames, temperature, noise)
        features = self.pose_stats.invert(features.double().cpu().numpy())
        return [decode_angles(f, self.skeleton, self.angle_spec, self.fps) for f in features]
