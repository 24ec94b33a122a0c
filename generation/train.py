"""Training any model on a motion dataset, with validation, checkpoints and resuming.

One loop serves every model: Adam, an optional Noam warm-up (MoGlow), gradient-norm
clipping, random minibatches of training windows, and at each evaluation the held-out
loss (MoGlow's held-out NLL) and a checkpoint written atomically.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from .checkpoint import CheckpointError, CheckpointMeta, code_version, load_checkpoint, load_optimizer_state, read_meta, save_checkpoint
from .models import model_class, preset
from .models.base import MotionModel
from .motion.dataset import MotionDataset

KEYS = ("pose", "control")


@dataclass(frozen=True)
class TrainOptions:
    steps: int = 2000
    eval_every: int = 250
    seed: int = 0
    device: str = "cpu"


def noam_factor(step: int, warmup: int) -> float:
    """The learning-rate factor of the Noam schedule, 1 at the end of the warm-up."""
    if warmup <= 0:
        return 1.0
    step = max(step, 1)
    return min(step / warmup, math.sqrt(warmup / step))


def tensors(dataset: MotionDataset, split: str, device: str) -> dict[str, torch.Tensor]:
    windows = dataset.windows(split, KEYS)
    if len(windows["pose"]) == 0:
        raise ValueError(f"the dataset has no {split} windows of {dataset.options.window_frames} frames")
    return {k: torch.as_tensor(v, dtype=torch.float32, device=device) for k, v in windows.items()}


@torch.no_grad()
def evaluate_loss(model: MotionModel, data: dict[str, torch.Tensor], batch_size: int = 64) -> float:
    """The mean loss over all windows (model in eval mode: no dropout)."""
    was_training = model.training
    model.eval()
    total, count = 0.0, 0
    for start in range(0, len(data["pose"]), batch_size):
        pose, control = data["pose"][start : start + batch_size], data["control"][start : start + batch_size]
        loss, _ = model.loss(pose, control)
        total += float(loss) * len(pose)
        count += len(pose)
    model.train(was_training)
    return total / count


def checkpoint_meta(model: MotionModel, dataset: MotionDataset, step: int, metrics: dict) -> CheckpointMeta:
    return CheckpointMeta(
        kind=model.kind,
        hyperparameters=dataclasses.asdict(model.config),
        pose_dim=model.pose_dim,
        control_dim=model.control_dim,
        features={"type": "positions", "dataset_options": dataset.options.to_dict()},
        stats={k: dataset.stats[k].to_dict() for k in KEYS},
        skeleton=dataset.skeleton.to_dict(),
        data_fingerprint=dataset.fingerprint,
        step=step,
        code_version=code_version(),
        metrics=metrics,
    )


def best_path(out: Path) -> Path:
    """Where the checkpoint with the lowest held-out loss so far is kept."""
    return out.with_name(out.name.removesuffix(".safetensors") + ".best.safetensors")


def train(
    kind: str,
    preset_name: str,
    dataset: MotionDataset,
    out: str | os.PathLike,
    options: TrainOptions = TrainOptions(),
    resume: bool = False,
    progress: bool = True,
) -> CheckpointMeta:
    """Train (or with ``resume`` continue) a model; returns the last checkpoint's description.

    ``out`` always holds the latest state (and its optimiser, for resuming);
    ``NAME.best.safetensors`` beside it the state with the lowest held-out loss.
    """
    out = Path(out)
    torch.manual_seed(options.seed)
    train_data, val_data = tensors(dataset, "train", options.device), tensors(dataset, "test", options.device)
    pose_dim, control_dim = train_data["pose"].shape[-1], train_data["control"].shape[-1]

    history: list[dict] = []
    if resume and out.exists():
        model, meta = load_checkpoint(out, options.device)
        if meta.data_fingerprint != dataset.fingerprint:
            raise CheckpointError(f"{out}: trained on other data (fingerprint {meta.data_fingerprint[:12]}, "
                                  f"this dataset {dataset.fingerprint[:12]}); cannot resume")
        model.train()
        start, history = meta.step, meta.metrics.get("history", [])
    else:
        model = model_class(kind)(preset(kind, preset_name), pose_dim, control_dim).to(options.device)
        start = 0
    config = model.config
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate)
    if start:
        load_optimizer_state(out, optimizer)
    warmup = getattr(config, "warmup_steps", 0)
    batches = torch.Generator(device="cpu").manual_seed(options.seed + start)

    elapsed = history[-1]["seconds"] if history else 0.0
    clock = time.perf_counter()
    bar = tqdm(range(start, options.steps), desc=f"training {kind}", unit="step", disable=not progress,
               initial=start, total=options.steps)
    recent: list[float] = []
    for step in bar:
        for group in optimizer.param_groups:
            group["lr"] = config.learning_rate * noam_factor(step + 1, warmup)
        index = torch.randint(len(train_data["pose"]), (config.batch_size,), generator=batches).to(options.device)
        loss, metrics = model.loss(train_data["pose"][index], train_data["control"][index])
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), config.grad_clip)
        optimizer.step()
        recent.append(loss.detach().item())
        if not np.isfinite(recent[-1]):
            raise FloatingPointError(f"the training loss became {recent[-1]} at step {step + 1}; "
                                     "try a lower learning rate or stronger gradient clipping")
        done = step + 1
        if done % options.eval_every == 0 or done == options.steps:
            val = evaluate_loss(model, val_data)
            seconds = elapsed + time.perf_counter() - clock
            history.append({"step": done, "train_loss": float(np.mean(recent)), "val_loss": val, "seconds": round(seconds, 1)})
            recent = []
            bar.set_postfix(train=f"{history[-1]['train_loss']:.3f}", val=f"{val:.3f}")
            meta = checkpoint_meta(model, dataset, done, {"val_loss": val, "history": history})
            save_checkpoint(out, model, meta, optimizer)
            # Small baselines overfit the few held-out takes early: keep the best as well.
            if val <= min(h["val_loss"] for h in history):
                save_checkpoint(best_path(out), model, meta)
    bar.close()
    return read_meta(out)
