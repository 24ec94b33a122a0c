"""Benchmark: MoGlow and baseline sampling and training speed on this machine.

Sampling frames/s at batch 1 and batch 64, and training steps/s, for the ``paper`` and
``cpu`` presets (63-D poses, 3-D control, 80-frame windows of the real data for ActNorm's
initialisation and the training steps). The reference is the authors' official MoGlow
implementation measured on this machine with the paper-sized model: 17.9 frames/s at
batch 1 and 570 frames/s at batch 64. That code is not part of this repository, so its
figures are constants here rather than re-measured in each run.

MoGlow samples in float32 (the default) and, on CPUs with bfloat16 units (AVX512-BF16 or
AMX), also in bfloat16 (the coupling networks' matrix products on those units; elsewhere
torch emulates bfloat16 far slower, so it is not measured). Targets: the paper preset
samples faster than real time (20 fps) at batch 1, a 4-second clip for each of 64
control signals takes under a minute, and ours beats the reference by 2x at both batch
sizes (each in the faster of the two precisions, named in the output). A second
reference, measured in the same run, is the ceiling of float32 sampling on this machine:
the coupling networks' matrix products of one frame alone, at the same shapes, with
nothing else (they are where sampling spends its time, in any implementation).

    python benchmarks/bench_models.py [--json] [--threads N] [--models moglow ...]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.machine import describe_machine  # noqa: E402
from generation.registry import model_class, preset, training_knobs  # noqa: E402
from generation.models.flows import AffineCoupling  # noqa: E402
from generation.models.moglow import cpu_has_bfloat16_units  # noqa: E402
from generation.motion.dataset import DatasetOptions, build_dataset  # noqa: E402

REFERENCE_FPS = {1: 17.9, 64: 570.0}  # official MoGlow, paper-sized, this machine
# MoGlow's precisions worth timing here; the baselines sample in float32 only.
PRECISIONS = ("float32", "bfloat16") if cpu_has_bfloat16_units() else ("float32",)
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right")


def windows(data: str) -> tuple[torch.Tensor, torch.Tensor]:
    dataset = build_dataset(data, DatasetOptions(contents=LOCOMOTION), progress=False)
    w = dataset.windows("train")
    return torch.as_tensor(w["pose"]), torch.as_tensor(w["control"])


def sampling_fps(model, control: torch.Tensor, batch: int, precision: str, frames: int = 80, repeats: int = 2) -> float:
    c = control[:1, :frames].expand(batch, -1, -1).contiguous()
    model.generate(c, None, 1.0, torch.Generator().manual_seed(0), precision)  # warm-up
    best = float("inf")
    for r in range(repeats):
        start = time.perf_counter()
        model.generate(c, None, 1.0, torch.Generator().manual_seed(r), precision)
        best = min(best, time.perf_counter() - start)
    generated = frames - model.context_frames
    return batch * generated / best


def coupling_products(model, batch: int) -> list[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
    """(bias, left, right) of every matrix product that sampling one frame of ``batch``
    sequences makes in MoGlow's coupling networks: the float32 sampler's own operands
    (per LSTM layer, (input, h) @ [W_ih W_hh]ᵀ; then the output layer), with random inputs."""
    products = []
    for transform in model.flow.transforms:
        if isinstance(transform, AffineCoupling):
            frame = transform.frame_inverse()
            for weight_t, bias in [*frame.layers, frame.out]:
                products.append((bias, torch.randn(batch, weight_t.shape[0]), weight_t))
    return products


def matrix_product_ceiling(model, batch: int, frames: int = 10, repeats: int = 3) -> tuple[float, float]:
    """(frames/s, GFLOP/s) of the coupling networks' matrix products alone, for ``frames``
    frames in a row, best of ``repeats``: what float32 sampling could reach on this machine
    if it did nothing else."""
    products = coupling_products(model, batch)
    flops = sum(2 * left.shape[0] * left.shape[1] * right.shape[1] for _, left, right in products)
    best = float("inf")
    for _ in range(repeats + 1):  # the first pass warms up
        start = time.perf_counter()
        for _ in range(frames):
            for bias, left, right in products:
                torch.addmm(bias, left, right)
        best = min(best, (time.perf_counter() - start) / frames)
    return batch / best, flops / best / 1e9


def training_steps_per_s(model, pose, control, batch: int, steps: int = 5) -> float:
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-4)
    model.train()
    times = []
    for step in range(steps + 1):
        index = torch.randint(len(pose), (batch,))
        start = time.perf_counter()
        loss, _ = model.loss(pose[index], control[index])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        times.append(time.perf_counter() - start)
    return 1.0 / (sum(times[1:]) / steps)  # the first step includes set-up


def run(data: str, kinds: tuple[str, ...] = ("moglow", "rnn", "vae")) -> dict:
    pose, control = windows(data)
    rows = []
    for kind in kinds:
        for name in ("paper", "cpu"):
            config, batch = preset(kind, name), training_knobs(kind, name)["batch_size"]
            torch.manual_seed(0)
            model = model_class(kind)(config, pose.shape[-1], control.shape[-1])
            model.train()
            with torch.no_grad():
                model.loss(pose[:64], control[:64])  # data-dependent initialisation (ActNorm)
            row = {"model": kind, "preset": name, "parameters": sum(p.numel() for p in model.parameters()),
                   "train_steps_per_s": round(training_steps_per_s(model, pose, control, batch), 2),
                   "train_batch": batch}
            model.eval()
            for precision in (p for p in model.precisions if p in PRECISIONS):
                for batch in (1, 64):
                    row[f"sample_fps_batch{batch}_{precision}"] = round(sampling_fps(model, control, batch, precision), 1)
            if kind == "moglow":
                for batch in (1, 64):
                    fps, gflops = matrix_product_ceiling(model, batch)
                    row[f"products_only_fps_batch{batch}"] = round(fps, 1)
                    row[f"products_gflops_batch{batch}"] = round(gflops, 1)
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    result = {"benchmark": "model sampling and training speed", "rows": rows, "reference_fps": REFERENCE_FPS}
    paper = next((r for r in rows if r["model"] == "moglow" and r["preset"] == "paper"), None)
    if paper is None:
        return {**result, "targets": {}}
    fastest = {batch: max(((paper[f"sample_fps_batch{batch}_{p}"], p) for p in PRECISIONS)) for batch in REFERENCE_FPS}
    targets = {
        f"paper batch 1 faster than real time (20 fps, {fastest[1][1]})": fastest[1][0] > 20,
        f"64 clips of 4 s in under a minute ({fastest[64][1]})": 64 * 80 / fastest[64][0] < 60,
        **{f"2x the official implementation at batch {batch} ({precision})": fps >= 2 * REFERENCE_FPS[batch]
           for batch, (fps, precision) in fastest.items()},
    }
    return {
        **result,
        **{f"ratio_batch{batch}_{p}": round(paper[f"sample_fps_batch{batch}_{p}"] / REFERENCE_FPS[batch], 2)
           for batch in REFERENCE_FPS for p in PRECISIONS},
        "targets": targets,
        "threads": torch.get_num_threads(),
        "machine": describe_machine(),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.environ.get("MOTION_DATA", "../shared/data/bandai-namco-1"))
    parser.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--models", nargs="+", choices=("moglow", "rnn", "vae"), default=("moglow", "rnn", "vae"))
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    result = run(args.data, tuple(args.models))
    if args.json:
        print(json.dumps(result))
    else:
        short = {"float32": "fp32", "bfloat16": "bf16"}
        columns = [(f"sample_fps_batch{b}_{p}", f"{short[p]} b={b}") for p in PRECISIONS for b in REFERENCE_FPS]
        print(f"{'model':<8}{'preset':<8}{'params':>12}{'train steps/s':>15}"
              + "".join(f"{title:>14}" for _, title in columns) + "   (sampling frames/s)")
        for r in result["rows"]:
            print(f"{r['model']:<8}{r['preset']:<8}{r['parameters']:>12,}{r['train_steps_per_s']:>15}"
                  + "".join(f"{r.get(key, '-'):>14}" for key, _ in columns))
        for r in result["rows"]:
            if "products_only_fps_batch1" in r:
                print(f"{r['model']} {r['preset']} float32 vs its coupling networks' matrix products alone "
                      f"(the ceiling on this machine): " + ", ".join(
                          f"batch {b}: {r[f'sample_fps_batch{b}_float32']} vs {r[f'products_only_fps_batch{b}']} frames/s "
                          f"({r[f'products_gflops_batch{b}']} GFLOP/s)" for b in (1, 64)))
        if "bfloat16" not in PRECISIONS:
            print("bfloat16 not measured: this CPU has no bfloat16 units (AVX512-BF16 or AMX)")
        for p in PRECISIONS if result["targets"] else ():
            print(f"MoGlow paper in {p} vs official implementation: {result[f'ratio_batch1_{p}']}x at batch 1, "
                  f"{result[f'ratio_batch64_{p}']}x at batch 64")
        for target, met in result["targets"].items():
            print(f"  {'met   ' if met else 'MISSED'} {target}")
    return 0 if all(result["targets"].values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
