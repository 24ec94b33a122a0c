"""Copies of real BVH clips as other rigs would write them: other joint names, CMU-style
zero-offset collars, other length units, z up. The motion is the same in every copy."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from generation.motion.bvh import BVH, motion_to_bvh, read_bvh, scale_lengths, write_bvh
from generation.motion.kinematics import subtree_motion
from generation.motion.rotations import matrix_to_quat, quat_to_matrix
from generation.motion.types import Motion, Skeleton
from measures.units import Z_UP_TO_Y_UP

SIDED = ("Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg", "LowerLeg", "Foot", "Toes")
CENTRAL = ("joint_Root", "Hips", "Spine", "Chest", "Neck", "Head")

# Bandai-Namco names in other conventions: (name of a left joint from its base name,
# of a right one, of a joint of neither side).
CONVENTIONS = {
    "Foot_L": (lambda b: f"{b}_L", lambda b: f"{b}_R", str),
    "foot_l": (lambda b: f"{b.lower()}_l", lambda b: f"{b.lower()}_r", str.lower),
    "Foot.L": (lambda b: f"{b}.L", lambda b: f"{b}.R", str),
    "L_Foot": (lambda b: f"L_{b}", lambda b: f"R_{b}", str),
    "l_foot": (lambda b: f"l_{b.lower()}", lambda b: f"r_{b.lower()}", str.lower),
    "LeftFoot": (lambda b: f"Left{b}", lambda b: f"Right{b}", str),
    "left_foot": (lambda b: f"left_{b.lower()}", lambda b: f"right_{b.lower()}", str.lower),
    "mixamorig:LeftFoot": (lambda b: f"mixamorig:Left{b}", lambda b: f"mixamorig:Right{b}", lambda b: f"mixamorig:{b}"),
    "LFoot (CMU)": (lambda b: f"L{b}", lambda b: f"R{b}", str),
    # The CMU database's own ASF names: lhand, lfemur, and "lowerback" is no left joint.
    "lfoot (CMU ASF)": (lambda b: f"l{b.lower()}", lambda b: f"r{b.lower()}",
                        lambda b: {"Spine": "lowerback", "Chest": "upperback"}.get(b, b.lower())),
}

# A CMU-style rig: CMU's joint names, and zero-offset hip joints and collars between the
# hips and the legs and between the chest and the shoulders.
CMU_NAMES = {
    "Hips": "Hips", "Spine": "LowerBack", "Chest": "Spine1", "Neck": "Neck", "Head": "Head",
    "Shoulder_L": "LeftClavicle", "UpperArm_L": "LeftArm", "LowerArm_L": "LeftForeArm", "Hand_L": "LeftHand",
    "UpperLeg_L": "LeftUpLeg", "LowerLeg_L": "LeftLeg", "Foot_L": "LeftFoot", "Toes_L": "LeftToeBase",
}
CMU_NAMES.update({k.replace("_L", "_R"): v.replace("Left", "Right") for k, v in CMU_NAMES.items() if k.endswith("_L")})
CMU_COLLARS = {"UpperLeg_L": "LHipJoint", "UpperLeg_R": "RHipJoint", "Shoulder_L": "LeftShoulder",
               "Shoulder_R": "RightShoulder"}


def convention_names(names: tuple[str, ...], convention: str) -> tuple[str, ...]:
    left, right, central = CONVENTIONS[convention]
    result = []
    for name in names:
        base, _, side = name.rpartition("_")
        result.append(left(base) if side == "L" and base in SIDED else
                      right(base) if side == "R" and base in SIDED else central(name))
    return tuple(result)


def renamed(motion: Motion, names: tuple[str, ...]) -> Motion:
    skeleton = replace(motion.skeleton, names=names)
    return Motion(motion.positions, motion.fps, skeleton, motion.rotations, motion.translations)


def cmu_style(motion: Motion) -> Motion:
    """The body (hips and below) with CMU names and zero-offset collars; every original
    joint stays where it was."""
    motion = subtree_motion(motion, motion.skeleton.index("Hips"))
    old, names, parents, source = motion.skeleton, [], [], []  # source: old joint or -1 for a collar
    new_index: dict[int, int] = {}
    for j, name in enumerate(old.names):
        parent = new_index.get(int(old.parents[j]), -1)
        if name in CMU_COLLARS:
            names.append(CMU_COLLARS[name]), parents.append(parent), source.append(-1)
            parent = len(names) - 1
        new_index[j] = len(names)
        names.append(CMU_NAMES[name]), parents.append(parent), source.append(j)
    source = np.array(source)
    real = source >= 0
    positions = np.zeros((motion.n_frames, len(names), 3))
    rotations = np.tile([1.0, 0.0, 0.0, 0.0], (motion.n_frames, len(names), 1))
    translations = np.zeros((motion.n_frames, len(names), 3))
    offsets = np.zeros((len(names), 3))
    positions[:, real] = motion.positions[:, source[real]]
    rotations[:, real] = motion.rotations[:, source[real]]
    translations[:, real] = motion.translations[:, source[real]]
    offsets[real] = old.offsets[source[real]]
    for k in np.nonzero(~real)[0]:  # a collar sits on its parent
        positions[:, k] = positions[:, parents[k]]
    end_sites = {new_index[j]: sites for j, sites in old.end_sites.items()}
    skeleton = Skeleton(tuple(names), np.array(parents), offsets, end_sites)
    return Motion(positions, motion.fps, skeleton, rotations, translations)


def z_up(motion: Motion) -> Motion:
    """The motion in a z-up world: the root turned by the inverse of the y-up conversion."""
    rotations, translations = motion.rotations.copy(), motion.translations.copy()
    rotations[:, 0] = matrix_to_quat(Z_UP_TO_Y_UP.T @ quat_to_matrix(motion.rotations[:, 0]))
    translations[:, 0] = motion.translations[:, 0] @ Z_UP_TO_Y_UP
    positions = motion.positions @ Z_UP_TO_Y_UP
    return Motion(positions, motion.fps, motion.skeleton, rotations, translations)


def in_unit(bvh: BVH, centimetres_per_unit: float) -> BVH:
    """The same file with every length written in another unit."""
    return scale_lengths(bvh, 1.0 / centimetres_per_unit)


def write_variants(source: Path, folder: Path) -> dict[str, Path]:
    """The clip as a CMU-style rig, in metres, in inches and z up; their paths by name."""
    bvh = read_bvh(source)
    motion = bvh.to_motion()
    folder.mkdir(parents=True, exist_ok=True)
    variants = {
        "cmu": motion_to_bvh(cmu_style(motion)),
        "metres": in_unit(bvh, 100.0),
        "inches": in_unit(bvh, 2.54),
        "z-up": motion_to_bvh(z_up(motion), "XYZ"),  # ZXY would meet gimbal lock at the root
        "cmu, z-up, inches": in_unit(motion_to_bvh(z_up(cmu_style(motion)), "XYZ"), 2.54),
    }
    return {name: write_bvh(variant, folder / f"{name.replace(', ', '-')}.bvh") for name, variant in variants.items()}
