"""Benchmark of `analysis` against the issue's targets; exits non-zero when one is missed.

    .venv/bin/python benchmarks/bench_analysis.py [--json] [--repeat N]

1. A full report (read CSV, exclusions, ANOVA, Tukey HSD, CIs, mixed model, every table
   in four formats, every figure in PNG and SVG) for 100,000 ratings over 10 systems and
   2 tasks: target 5 s.
   The same for side-by-side pages (about 100,000 ratings: 3,400 participants x 6 pages
   x 5 systems) and pairwise pages (50,000 pages), reported beside it (Wilcoxon tests,
   preference tests, Bradley-Terry, the power table), against the same target.
2. Objective metrics (footstep curves, v_tol^(95), step durations, bone-length RMSE)
   for 1,000 clips of 4 s at 20 fps on a 22-joint skeleton: target 10 s.

Times are wall-clock inside one process, best of --repeat runs, after imports
(interpreter start-up and importing scipy/matplotlib are reported separately: they are
paid once per process, not per report).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

_t0 = time.perf_counter()
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import scipy  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from analysis.motion.motion_io import SystemClips  # noqa: E402
from analysis.motion.objective import objective_metrics  # noqa: E402
from analysis.ratings.schema import read_ratings  # noqa: E402
from analysis.reports.single_report import write_report  # noqa: E402
from analysis.ratings.report import build_report
from analysis.ratings.simulate import (simulate_pairwise, simulate_ratings,  # noqa: E402
                               simulate_side_by_side)
from benchmarks.machine import describe_machine  # noqa: E402

IMPORT_S = time.perf_counter() - _t0
REPORT_TARGET_S = 5.0
OBJECTIVE_TARGET_S = 10.0


def machine() -> dict:
    return {**describe_machine(), "scipy": scipy.__version__, "pandas": pd.__version__,
            "matplotlib": matplotlib.__version__}


# The simulated ratings each design's report is timed on, by design.
SIMULATED = {
    "single": lambda: simulate_ratings({"NAT": 4.2, **{f"S{i}": 2.6 + 0.15 * i for i in range(9)}}, 100_000,
                                       tasks=("locomotion", "gestures"), seed=1),
    "side-by-side": lambda: simulate_side_by_side({"NAT": 78, "A": 62, "B": 58, "C": 45, "BAD": 12},
                                                  n_participants=3400, pages_per_participant=6, seed=1),
    "pairwise": lambda: simulate_pairwise({"NAT": 1.0, "A": 0.4, "B": 0.2, "C": -0.3, "BAD": -5.0},
                                          n_participants=2500, pages_per_participant=20, seed=1),
}


def bench_report(folder: Path, design: str = "single") -> float:
    ratings = SIMULATED[design]()
    path = folder / "ratings.csv"
    ratings.to_csv(path, index=False)
    start = time.perf_counter()
    write_report(build_report(read_ratings(path)), folder / "report")
    return time.perf_counter() - start


def synthetic_walks(system: str, n_clips: int, seconds: float, fps: float, seed: int) -> SystemClips:
    """Clips on a 22-joint chain skeleton whose two feet alternate stance and swing."""
    rng = np.random.default_rng(seed)
    joints = 22
    parents = np.arange(-1, joints - 1)
    offsets = np.zeros((joints, 3))
    offsets[1:, 1] = 5.0
    frames = int(seconds * fps)
    t = np.arange(frames) / fps
    rest = np.cumsum(offsets, axis=0)
    clips = []
    for _ in range(n_clips):
        phase = rng.uniform(0, 2 * np.pi)
        forward = 100.0 * t + rng.normal(0, 0.3, frames)
        clip = np.broadcast_to(rest, (frames, joints, 3)).copy()
        clip[:, :, 2] += forward[:, None]
        for foot, shift in ((5, 0.0), (10, np.pi)):
            # each foot advances in bursts (swing) and rests (stance), 1 stride per second
            swing = np.maximum(0.0, np.sin(2 * np.pi * t + phase + shift))
            clip[:, foot, 2] = np.cumsum(swing) / swing.sum() * forward[-1]
        clips.append(clip)
    names = tuple("Foot_L" if j == 5 else "Foot_R" if j == 10 else f"joint{j}" for j in range(joints))
    return SystemClips(system, fps, names, parents, offsets, clips)


def bench_objective() -> float:
    motion = {f"S{i}": synthetic_walks(f"S{i}", 250, 4.0, 20.0, seed=i) for i in range(4)}
    start = time.perf_counter()
    objective_metrics(motion)
    return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--repeat", type=int, default=3, help="runs per benchmark (best is kept)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        design_s = {kind: min(bench_report(Path(tmp), kind) for _ in range(args.repeat)) for kind in SIMULATED}
    objective_s = min(bench_objective() for _ in range(args.repeat))
    results = {
        "machine": machine(), "import_s": round(IMPORT_S, 3),
        "full_report_100k_ratings_s": round(design_s["single"], 3), "full_report_target_s": REPORT_TARGET_S,
        "side_by_side_report_100k_ratings_s": round(design_s["side-by-side"], 3),
        "pairwise_report_50k_pages_s": round(design_s["pairwise"], 3),
        "objective_1000_clips_s": round(objective_s, 3), "objective_target_s": OBJECTIVE_TARGET_S,
    }
    passed = (max(design_s.values()) < REPORT_TARGET_S
              and objective_s < OBJECTIVE_TARGET_S)
    results["passed"] = passed
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        m = results["machine"]
        print(f"machine: {m['cpu']}, {m['cores']} cores, {m['system']}, Python {m['python']}, "
              f"numpy {m['numpy']}, scipy {m['scipy']}, pandas {m['pandas']}, "
              f"matplotlib {m['matplotlib']}")
        print(f"imports (once per process): {IMPORT_S:.2f} s")
        print(f"full report, 100,000 ratings x 10 systems x 2 tasks: {design_s['single']:.2f} s "
              f"(target {REPORT_TARGET_S:g} s) {'ok' if design_s['single'] < REPORT_TARGET_S else 'MISSED'}")
        for design, seconds in design_s.items():
            print(f"full report, {design} pages: {seconds:.2f} s (target {REPORT_TARGET_S:g} s) "
                  f"{'ok' if seconds < REPORT_TARGET_S else 'MISSED'}")
        print(f"objective metrics, 1,000 clips of 4 s at 20 fps: {objective_s:.2f} s "
              f"(target {OBJECTIVE_TARGET_S:g} s) {'ok' if objective_s < OBJECTIVE_TARGET_S else 'MISSED'}")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
