"""Benchmark: HVRNN, ERD and QuaterNet training and sampling speed on this machine.

For the ``paper`` and ``cpu`` presets of each model: training steps/s (the preset's
batch size, real labelled sequences; HVRNN with every loss term switched on, i.e. the
schedules past their ramps and the attribute classifiers in the loss) and sampling
speed in 200-frame (6.7 s at 30 fps) sequences per second at batch 1 and batch 64.
The figures are reported against two references: real time (seconds of motion made
per second), and ERD of the same preset, measured in the same run (a plain
frame-by-frame recurrent sampler, the cheapest model of the three per frame).
Targets: every preset samples faster than real time at batch 1, and 64 sequences of
each label pair take under a minute.

    python benchmarks/bench_hvrnn.py [--json] [--threads N] [--models hvrnn erd quaternet]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.machine import describe_machine  # noqa: E402
from generation.hvrnn.classifiers import AttributeClassifiers, ClassifierConfig  # noqa: E402
from generation.hvrnn.data import MAX_FRAMES, load_attribute_data  # noqa: E402
from generation.registry import model_class, preset, training_knobs  # noqa: E402
from generation.train import load_loss_classifiers  # noqa: E402

KINDS = ("hvrnn", "erd", "quaternet")


def build(kind: str, name: str, data, classifiers_path: str):
    config = dataclasses.replace(preset(kind, name), actions=data.actions.names, styles=data.styles.names)
    torch.manual_seed(0)
    model = model_class(kind)(config, data.feature_dim, len(data.actions) + len(data.styles))
    model.prepare(data)
    if kind == "hvrnn":  # measure the last phase of training, with every loss term on
        load_loss_classifiers(model, classifiers_path)
        model.step.fill_(config.classifier_start + config.classifier_ramp + config.kl_warmup + config.kl_anneal)
    return model


def training_steps_per_s(model, batches: dict[str, torch.Tensor], batch: int, steps: int = 4) -> float:
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-4)
    model.train()
    times = []
    for _ in range(steps + 1):
        index = torch.randint(len(batches["pose"]), (batch,))
        start = time.perf_counter()
        loss, _ = model.loss(**{k: v[index] for k, v in batches.items()})
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        times.append(time.perf_counter() - start)
    return 1.0 / (sum(times[1:]) / steps)  # the first step includes set-up


@torch.no_grad()
def sequences_per_s(model, batch: int, repeats: int = 2) -> float:
    model.eval()
    labels = torch.zeros(batch, dtype=torch.long)
    best = float("inf")
    for r in range(repeats + 1):  # the first run warms up
        start = time.perf_counter()
        model.generate(labels, labels, MAX_FRAMES, 1.0, torch.Generator().manual_seed(r))
        if r:
            best = min(best, time.perf_counter() - start)
    return batch / best


def run(data_folder: str, kinds: tuple[str, ...]) -> dict:
    data = load_attribute_data(data_folder, progress=False)
    pose, mask, action, style = data.sequences("train", data.standardizer("root")).tensors()
    batches = {"pose": pose, "mask": mask, "action": action, "style": style}
    seconds_per_sequence = MAX_FRAMES / data.fps
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        classifiers = AttributeClassifiers(ClassifierConfig(), data.feature_dim, data.actions, data.styles)
        classifiers_path = str(classifiers.save(Path(tmp) / "classifiers.safetensors", data.dataset.fingerprint, {}))
        for kind in kinds:
            for name in ("paper", "cpu"):
                model, train_batch = build(kind, name, data, classifiers_path), training_knobs(kind, name)["batch_size"]
                row = {"model": kind, "preset": name, "parameters": sum(p.numel() for p in model.parameters()),
                       "train_batch": train_batch,
                       "train_steps_per_s": round(training_steps_per_s(model, batches, train_batch), 3)}
                for batch in (1, 64):
                    row[f"sequences_per_s_batch{batch}"] = round(sequences_per_s(model, batch), 3)
                    row[f"real_time_factor_batch{batch}"] = round(row[f"sequences_per_s_batch{batch}"] * seconds_per_sequence, 1)
                rows.append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)
    erd = {r["preset"]: r for r in rows if r["model"] == "erd"}
    for row in rows:
        if row["preset"] in erd:
            for key in ("train_steps_per_s", "sequences_per_s_batch1", "sequences_per_s_batch64"):
                row[f"{key}_vs_erd"] = round(row[key] / erd[row["preset"]][key], 2)
    targets = {}
    for row in rows:
        label = f"{row['model']} {row['preset']}"
        targets[f"{label}: faster than real time at batch 1"] = row["real_time_factor_batch1"] > 1
        targets[f"{label}: 64 sequences of 200 frames in under a minute"] = 64 / row["sequences_per_s_batch64"] < 60
    return {"benchmark": "attribute-controlled models' training and sampling speed", "rows": rows,
            "frames_per_sequence": MAX_FRAMES, "fps": data.fps, "targets": targets,
            "threads": torch.get_num_threads(), "machine": describe_machine()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.environ.get("MOTION_DATA", "../shared/data/bandai-namco-1"))
    parser.add_argument("--threads", type=int, help="torch CPU threads (default: torch's choice)")
    parser.add_argument("--models", nargs="+", choices=KINDS, default=KINDS)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    result = run(args.data, tuple(args.models))
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{'model':<10}{'preset':<8}{'params':>12}{'train steps/s':>15}{'seq/s b=1':>11}{'seq/s b=64':>12}"
              f"{'x real time b=1':>17}{'b=64':>8}{'vs ERD b=1':>12}{'b=64':>7}")
        for r in result["rows"]:
            print(f"{r['model']:<10}{r['preset']:<8}{r['parameters']:>12,}{r['train_steps_per_s']:>15}"
                  f"{r['sequences_per_s_batch1']:>11}{r['sequences_per_s_batch64']:>12}"
                  f"{r['real_time_factor_batch1']:>17}{r['real_time_factor_batch64']:>8}"
                  f"{r.get('sequences_per_s_batch1_vs_erd', '-'):>12}{r.get('sequences_per_s_batch64_vs_erd', '-'):>7}")
        for target, met in result["targets"].items():
            print(f"  {'met   ' if met else 'MISSED'} {target}")
    return 0 if all(result["targets"].values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
