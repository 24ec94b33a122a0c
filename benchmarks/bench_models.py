"""Benchmark: MoGlow and baseline sampling and training speed on this machine.

Sampling frames/s at batch 1 and batch 64, and training steps/s, for the ``paper`` and
``cpu`` presets (63-D poses, 3-D control, 80-frame windows of the real data for ActNorm's
initialisation and the training steps). MoGlow samples in every precision this CPU
multiplies natively (``generation.models.precision``: float32; bfloat16 with AVX512-BF16
or AMX; int8 with fbgemm), and "auto" (the default of ``sample`` and of the study's
workers) names one of them.

The reference is the authors' MoGlow at the paper's size. With ``$MOGLOW_REFERENCE_CODE``
naming a checkout of their code (``benchmarks/moglow_reference.py``; it is obtained
separately, never part of this repository) it is measured in this run: their model and
sampling loop and ours alternate, ``--repetitions`` times, so that drift of a shared
machine reaches both, and each ratio is ours over theirs within one repetition. Without
it the reference is two constants measured on an earlier machine (17.9 frames/s at
batch 1, 570 at batch 64) and the output says so.

Targets: the paper preset samples faster than real time (20 fps) at batch 1, a 4-second
clip for each of 64 control signals takes under a minute, and ours is at least 2x the
reference at both batch sizes, each in the default precision (median of the
repetitions). Two ceilings are measured in the same run: the coupling networks' matrix
products of one frame alone, at the sampler's shapes and precision (where sampling spends
its time, in any implementation), and at batch 1 the memory-bandwidth limit: the bytes
of those weights, which do not fit in any cache and are read once per frame, against the
machine's copy bandwidth (bytes read plus bytes written per second).

    MOGLOW_REFERENCE_CODE=PATH python benchmarks/bench_models.py [--json] [--threads N] [--models moglow ...]
        [--repetitions N] [--no-training] [--batches 64]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.machine import describe_machine  # noqa: E402
from benchmarks.moglow_reference import ENVIRONMENT_VARIABLE, ReferenceSampler, reference_code  # noqa: E402
from generation.registry import model_class, preset, training_knobs  # noqa: E402
from generation.models.flows import AffineCoupling  # noqa: E402
from generation.models.precision import (PRECISIONS, auto_precision, cpu_has_bfloat16_units,  # noqa: E402
                                         cpu_has_int8_products, input_dtype, matrix_product)
from generation.motion.dataset import build_dataset  # noqa: E402
from generation.motion.dataset_options import DatasetOptions  # noqa: E402

REFERENCE_CONSTANTS = {1: 17.9, 64: 570.0}  # the authors' MoGlow, paper-sized, an earlier 2-core machine
BATCHES = (1, 64)
# The precisions worth timing here: emulated bfloat16 is many times slower than float32.
MEASURED = tuple(p for p in PRECISIONS if p == "float32" or (p == "bfloat16" and cpu_has_bfloat16_units())
                 or (p == "int8" and cpu_has_int8_products()))
DEFAULT = auto_precision("cpu", PRECISIONS)
WEIGHT_BYTES = {"float32": 4, "bfloat16": 2, "int8": 1}
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right")


def windows(data: str) -> tuple[torch.Tensor, torch.Tensor]:
    dataset = build_dataset(data, DatasetOptions(contents=LOCOMOTION), progress=False)
    w = dataset.windows("train")
    return torch.as_tensor(w["pose"]), torch.as_tensor(w["control"])


def sampling_seconds(model, control: torch.Tensor, precision: str, seed: int = 0) -> float:
    start = time.perf_counter()
    model.generate(control, None, 1.0, torch.Generator().manual_seed(seed), precision)
    return time.perf_counter() - start


def sampling_fps(model, control: torch.Tensor, batch: int, precision: str, frames: int = 80, repeats: int = 2) -> float:
    c = control[:1, :frames].expand(batch, -1, -1).contiguous()
    sampling_seconds(model, c, precision)  # warm-up
    best = min(sampling_seconds(model, c, precision, seed=r) for r in range(repeats))
    return batch * (frames - model.context_frames) / best


def coupling_weights(model) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """(weight, bias) of every matrix product that sampling one frame makes in MoGlow's
    coupling networks, the sampler's own operands."""
    return [product for transform in model.flow.transforms if isinstance(transform, AffineCoupling)
            for product in transform.frame_products()]


def matrix_product_ceiling(model, batch: int, precision: str, frames: int = 10, repeats: int = 3) -> float:
    """Frames/s of the coupling networks' matrix products alone in ``precision``, for
    ``frames`` frames in a row with random inputs, best of ``repeats``: what sampling could
    reach on this machine if it did nothing else."""
    with torch.inference_mode():
        products = [(matrix_product(w, b, precision), torch.randn(batch, w.shape[1]).to(input_dtype(precision, w.dtype)))
                    for w, b in coupling_weights(model)]
        best = float("inf")
        for _ in range(repeats + 1):  # the first pass warms up
            start = time.perf_counter()
            for _ in range(frames):
                for product, x in products:
                    product(x)
            best = min(best, (time.perf_counter() - start) / frames)
    return batch / best


def copy_bandwidth(megabytes: int = 512, repeats: int = 5) -> float:
    """GB/s that copying a buffer far larger than the caches moves (read plus written), best of ``repeats``."""
    source = torch.ones(megabytes * 2**20 // 4)
    target = torch.empty_like(source)
    best = float("inf")
    for _ in range(repeats + 1):
        start = time.perf_counter()
        target.copy_(source)
        best = min(best, time.perf_counter() - start)
    return 2 * source.numel() * 4 / best / 1e9


def paper_sampling(model, control: torch.Tensor, code: Path | None, repetitions: int,
                   batches: tuple[int, ...] = BATCHES, frames: int = 80) -> dict:
    """Ours in every measured precision and the reference, alternating, at each batch size;
    frames/s per repetition, ratios within each, and the two ceilings (the bandwidth limit
    where batch 1 is measured)."""
    control = control[:1, :frames]
    ours = {batch: control.expand(batch, -1, -1).contiguous() for batch in batches}
    generated = frames - model.context_frames
    references = {batch: ReferenceSampler(code, control[0].numpy(), model.pose_dim, batch) for batch in batches} if code else {}
    for batch in batches:  # warm-up
        for precision in MEASURED:
            sampling_seconds(model, ours[batch], precision)
        if code:
            references[batch].seconds()
    fps: dict[str, list[float]] = {}
    bandwidth = []
    for repetition in range(repetitions):
        bandwidth.append(copy_bandwidth())
        for batch in batches:
            if code:
                fps.setdefault(f"reference_batch{batch}", []).append(batch * references[batch].frames / references[batch].seconds())
            for precision in MEASURED:
                seconds = sampling_seconds(model, ours[batch], precision, seed=repetition)
                fps.setdefault(f"{precision}_batch{batch}", []).append(batch * generated / seconds)
        print(f"repetition {repetition + 1}/{repetitions}: " + ", ".join(f"{k} {v[-1]:.1f}" for k, v in fps.items()),
              file=sys.stderr, flush=True)
    reference = {batch: fps[f"reference_batch{batch}"] if code else [REFERENCE_CONSTANTS[batch]] * repetitions
                 for batch in batches}
    ratio = {f"{p}_batch{b}": [ours / theirs for ours, theirs in zip(fps[f"{p}_batch{b}"], reference[b])]
             for p in MEASURED for b in batches}
    weights = sum(w.numel() for w, _ in coupling_weights(model))
    weight_bytes = {p: weights * WEIGHT_BYTES[p] for p in MEASURED}
    limit = {p: statistics.median(bandwidth) * 1e9 / weight_bytes[p] for p in MEASURED}
    result = {
        "reference": (f"the authors' code at {code}, {references[batches[0]].parameters:,} parameters, same run" if code else
                      f"constants from an earlier machine (${ENVIRONMENT_VARIABLE} not set)"),
        "repetitions": repetitions,
        "fps": {k: [round(x, 1) for x in v] for k, v in fps.items()},
        "ratio": {k: [round(x, 2) for x in v] for k, v in ratio.items()},
        "products_only_fps": {f"{p}_batch{b}": round(matrix_product_ceiling(model, b, p), 1) for p in MEASURED for b in batches},
        "copy_bandwidth_gb_s": [round(x, 1) for x in bandwidth],
        "weight_bytes_per_frame": weight_bytes,
        "bandwidth_limit_fps_batch1": {p: round(x, 1) for p, x in limit.items()},
    }
    if 1 in batches:
        result["of_bandwidth_limit_batch1"] = {p: round(statistics.median(fps[f"{p}_batch1"]) / limit[p], 2) for p in MEASURED}
    return result


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


def run(data: str, kinds: tuple[str, ...], repetitions: int, training: bool = True,
        batches: tuple[int, ...] = BATCHES) -> dict:
    pose, control = windows(data)
    code = reference_code()
    rows, paper = [], None
    load = [round(x, 1) for x in os.getloadavg()]
    for kind in kinds:
        for name in ("paper", "cpu"):
            config, batch = preset(kind, name), training_knobs(kind, name)["batch_size"]
            torch.manual_seed(0)
            model = model_class(kind)(config, pose.shape[-1], control.shape[-1])
            model.train()
            with torch.no_grad():
                model.loss(pose[:64], control[:64])  # data-dependent initialisation (ActNorm)
            row = {"model": kind, "preset": name, "parameters": sum(p.numel() for p in model.parameters())}
            if training:
                row.update(train_steps_per_s=round(training_steps_per_s(model, pose, control, batch), 2), train_batch=batch)
            model.eval()
            if (kind, name) == ("moglow", "paper"):
                paper = paper_sampling(model, control, code, repetitions, batches)
                row.update({f"sample_fps_batch{b}_{p}": round(statistics.median(paper["fps"][f"{p}_batch{b}"]), 1)
                            for p in MEASURED for b in batches})
            else:
                row.update({f"sample_fps_batch{b}_{p}": round(sampling_fps(model, control, b, p), 1)
                            for p in model.precisions if p in MEASURED for b in batches})
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    result = {"benchmark": "model sampling and training speed", "rows": rows, "default_precision": DEFAULT,
              "threads": torch.get_num_threads(), "machine": describe_machine(),
              "load_average_before_after": [load, [round(x, 1) for x in os.getloadavg()]]}
    if paper is None:
        return {**result, "targets": {}}
    fps = {b: statistics.median(paper["fps"][f"{DEFAULT}_batch{b}"]) for b in batches}
    ratio = {b: statistics.median(paper["ratio"][f"{DEFAULT}_batch{b}"]) for b in batches}
    targets = {f"2x the reference at batch {b} ({DEFAULT}, median of the repetitions)": ratio[b] >= 2 for b in batches}
    if 1 in fps:
        targets[f"paper batch 1 faster than real time (20 fps, {DEFAULT})"] = fps[1] > 20
    if 64 in fps:
        targets[f"64 clips of 4 s in under a minute ({DEFAULT})"] = 64 * 80 / fps[64] < 60
    return {**result, "paper_sampling": paper, "targets": targets}


def spread(values: list[float]) -> str:
    """A repetition's figures as 'median (min–max)'."""
    return f"{statistics.median(values):g} ({min(values):g}–{max(values):g})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.environ.get("MOTION_DATA", "../shared/data/bandai-namco-1"))
    parser.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--models", nargs="+", choices=("moglow", "rnn", "vae"), default=("moglow", "rnn", "vae"))
    parser.add_argument("--repetitions", type=int, default=5, help="alternations of ours and the reference (default %(default)s)")
    parser.add_argument("--no-training", action="store_true", help="time sampling only")
    parser.add_argument("--batches", nargs="+", type=int, choices=BATCHES, default=BATCHES,
                        help="sampling batch sizes (default: %(default)s)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    batches = tuple(sorted(set(args.batches)))
    result = run(args.data, tuple(args.models), args.repetitions, not args.no_training, batches)
    if args.json:
        print(json.dumps(result))
    else:
        columns = [(f"sample_fps_batch{b}_{p}", f"{p} b={b}") for p in MEASURED for b in batches]
        print(f"{'model':<8}{'preset':<8}{'params':>12}{'train steps/s':>15}"
              + "".join(f"{title:>15}" for _, title in columns) + "   (sampling frames/s)")
        for r in result["rows"]:
            print(f"{r['model']:<8}{r['preset']:<8}{r['parameters']:>12,}{r.get('train_steps_per_s', '-'):>15}"
                  + "".join(f"{r.get(key, '-'):>15}" for key, _ in columns))
        print(f"default precision here (auto): {DEFAULT}; not measured: "
              f"{', '.join(p for p in PRECISIONS if p not in MEASURED) or 'none'}")
        paper = result.get("paper_sampling")
        if paper:
            print(f"MoGlow paper, frames/s as median (min–max) of {paper['repetitions']} repetitions; "
                  f"reference: {paper['reference']}")
            for b in batches:
                reference = paper["fps"].get(f"reference_batch{b}", [REFERENCE_CONSTANTS[b]])
                print(f"  batch {b}: reference {spread(reference)}; " + "; ".join(
                    f"{p} {spread(paper['fps'][f'{p}_batch{b}'])} = {spread(paper['ratio'][f'{p}_batch{b}'])}x, "
                    f"products alone {paper['products_only_fps'][f'{p}_batch{b}']}" for p in MEASURED))
        if paper and 1 in batches:
            print(f"  batch 1 against memory bandwidth (copy {spread(paper['copy_bandwidth_gb_s'])} GB/s read + written): "
                  + "; ".join(f"{p} {paper['weight_bytes_per_frame'][p] / 1e6:.0f} MB of weights per frame, "
                              f"limit {paper['bandwidth_limit_fps_batch1'][p]} frames/s, sampler at "
                              f"{paper['of_bandwidth_limit_batch1'][p]} of it" for p in MEASURED))
        print(f"load average (1, 5, 15 min) before and after: {result['load_average_before_after']}")
        for target, met in result["targets"].items():
            print(f"  {'met   ' if met else 'MISSED'} {target}")
    return 0 if all(result["targets"].values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
