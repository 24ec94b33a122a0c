"""Benchmark: a study worker's sampling of one system, batched against one clip at a time.

A sampling task samples every control of a system with ``Generator.sample_batch`` (each
clip from its own seed, STUDY_SAMPLE_BATCH at a time); the reference is what it did
before, ``Generator.sample(control, n=1, seed)`` for each control in turn. Both sample
the same ``--controls`` 4 s preset paths (the presets in turn) with the same seeds, in
the default ("auto") precision, and the batched clips are checked against the single
ones (largest difference in cm). Timings are the best of ``--repeats`` runs.

    python benchmarks/bench_batch_sampling.py [--checkpoint models/moglow-cpu.safetensors] [--controls 16]
        [--repeats 2] [--threads N] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.machine import describe_machine  # noqa: E402
from generation.control import PRESETS, preset_path  # noqa: E402
from generation.generator import Generator  # noqa: E402

DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[1] / "models" / "moglow-cpu.safetensors"
FOUR_SECONDS = [name for name, spec in PRESETS.items() if sum(s["seconds"] for s in spec["segments"]) == 4]


def best_time(run, repeats: int) -> tuple[float, list]:
    best, result = float("inf"), None
    for _ in range(repeats):
        started = time.perf_counter()
        result = run()
        best = min(best, time.perf_counter() - started)
    return best, result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--checkpoint", type=Path, default=DEFAULT_CHECKPOINT)
    parser.add_argument("--controls", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)
    generator = Generator.load(args.checkpoint)
    controls = [preset_path(FOUR_SECONDS[i % len(FOUR_SECONDS)], generator.fps) for i in range(args.controls)]
    seeds = list(range(args.controls))
    generator.sample(controls[0], n=1, seed=0)  # warm-up: lazy initialisation, caches

    batched_s, batched = best_time(lambda: generator.sample_batch(controls, seeds), args.repeats)
    single_s, single = best_time(lambda: [generator.sample(c, n=1, seed=s)[0] for c, s in zip(controls, seeds)],
                                 args.repeats)
    frames = sum(c.n_frames for c in controls)
    result = {
        "machine": describe_machine(),
        "checkpoint": str(args.checkpoint),
        "precision": generator.resolve_precision(),
        "threads": torch.get_num_threads(),
        "controls": args.controls,
        "frames": frames,
        "batched_s": batched_s,
        "one_at_a_time_s": single_s,
        "speedup": single_s / batched_s,
        "batched_frames_per_s": frames / batched_s,
        "one_at_a_time_frames_per_s": frames / single_s,
        "largest_difference_cm": max(float(np.abs(b.positions - s.positions).max()) for b, s in zip(batched, single)),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"{args.controls} controls of 4 s, {args.checkpoint.name}, precision {result['precision']}, "
              f"{result['threads']} threads on {result['machine']['cpu']}")
        print(f"  one batch:        {batched_s:7.2f} s  ({result['batched_frames_per_s']:.0f} frames/s)")
        print(f"  one at a time:    {single_s:7.2f} s  ({result['one_at_a_time_frames_per_s']:.0f} frames/s)")
        print(f"  speed-up {result['speedup']:.1f}x; batched clips within {result['largest_difference_cm']:.3g} cm "
              "of the single ones")
    return 0


if __name__ == "__main__":
    sys.exit(main())
