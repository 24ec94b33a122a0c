"""Benchmark: parse and forward-kinematics the whole shared data set.

Target (issue "Foundation"): all 174 clips in under 10 s. The reference is the common
way of doing it: a frame-by-frame, joint-by-joint loop with scipy's Rotation, as many
public BVH loaders do; it runs on a subset and is reported as frames/s.

    python benchmarks/bench_motion.py [--data FOLDER] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.machine import describe_machine  # noqa: E402
from generation.motion import read_bvh  # noqa: E402
from generation.motion.clip_files import find_bvh_files  # noqa: E402

TARGET_SECONDS = 10.0


def reference_positions(bvh) -> np.ndarray:
    """Joint positions frame by frame and joint by joint (the slow, common way)."""
    skeleton = bvh.skeleton
    columns = bvh.channel_columns()
    out = np.empty((len(bvh.values), skeleton.n_joints, 3))
    for t, row in enumerate(bvh.values):
        world_rot = []
        for j, names in enumerate(bvh.channels):
            values = dict(zip(names, row[columns[j].start : columns[j].stop]))
            order = "".join(n[0] for n in names if n.endswith("rotation"))
            local = Rotation.from_euler(order, [values[f"{a}rotation"] for a in order], degrees=True)
            offset = np.array([values.get(f"{a}position", skeleton.offsets[j][i]) for i, a in enumerate("XYZ")])
            p = skeleton.parents[j]
            if p < 0:
                world_rot.append(local)
                out[t, j] = offset
            else:
                world_rot.append(world_rot[p] * local)
                out[t, j] = out[t, p] + world_rot[p].apply(offset)
    return out


def run(data: Path) -> dict:
    files = find_bvh_files(data)
    start = time.perf_counter()
    frames = 0
    for path in files:
        frames += read_bvh(path).to_motion().n_frames
    ours = time.perf_counter() - start

    subset = files[:6]
    bvhs = [read_bvh(p) for p in subset]
    start = time.perf_counter()
    ref_frames = sum(len(reference_positions(b)) for b in bvhs)
    ref_fk = time.perf_counter() - start
    start = time.perf_counter()
    for b in bvhs:
        b.to_motion()
    our_fk = time.perf_counter() - start
    return {
        "benchmark": "parse + forward kinematics of the shared data",
        "clips": len(files),
        "frames": frames,
        "seconds": round(ours, 3),
        "frames_per_second": round(frames / ours),
        "target_seconds": TARGET_SECONDS,
        "met": ours < TARGET_SECONDS,
        "fk_reference_frames_per_second": round(ref_frames / ref_fk),
        "fk_ours_frames_per_second": round(ref_frames / our_fk),
        "fk_speedup": round(ref_fk / our_fk, 1),
        "machine": describe_machine(),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=os.environ.get("MOTION_DATA", "../shared/data/bandai-namco-1"))
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    args = parser.parse_args()
    result = run(Path(args.data))
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{result['clips']} clips, {result['frames']} frames parsed with forward kinematics in "
              f"{result['seconds']} s ({result['frames_per_second']} frames/s; target < {TARGET_SECONDS} s: "
              f"{'met' if result['met'] else 'MISSED'})")
        print(f"forward kinematics alone: {result['fk_ours_frames_per_second']} frames/s vs "
              f"{result['fk_reference_frames_per_second']} frames/s for a per-frame scipy loop ({result['fk_speedup']}x)")
    return 0 if result["met"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
