"""Real motion as other labs' files: Bandai-Namco walks (``../shared/data``) on the rig of
the CMU database's 3ds Max-friendly BVH conversion, in CMU units and in metres, and on
ACCAD's rig with CMU's ASF names.

The project keeps no motion capture of its own, so the tests write these files
themselves. Each reproduces what set the real files of its source apart when they were
tried (CMU subject 131's "start, walk, stop" and ACCAD's "Swagger" walk):

- **CMU, 3ds Max-friendly** (31 joints, 120 fps, lengths in CMU units of 5.644 cm,
  rotation channels ZYX): the spine starts at ``lowerback``, the hips' first child
  that is not a leg, whose ``OFFSET`` is ``0 0 0``; so are ``LHipJoint``/``RHipJoint``
  above the legs, ``lowerneck``, ``lhand``/``rhand`` and the thumbs. The header's lines
  end in CRLF and the motion's in LF; a zero offset is written ``0 0 0``.
- **The same in metres**, as a later conversion of the CMU-unit file wrote it: every
  length of that file's numbers rescaled, six decimals, a space before each line's end,
  LF throughout.
- **ACCAD** (22 joints, 120 fps, centimetres, ZXY): the root is named ``root`` (no joint
  is called hips or pelvis), the spine starts at a zero-offset ``lowerback``, the legs
  hang from the root after the spine, the right leg first; two-space indents, CRLF
  throughout, a tab after ``Frames:`` and ``Frame Time:``.

The rest pose of each rig is the take's first frame turned to face +z (every bone where
the body had it, as a capture's T-pose is), so the joints' rotations are the take's own
re-expressed on that rest pose, and forward kinematics gives the take's positions (to
the files' rounding).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from generation.motion.bvh import BVH, POSITION_AXIS, motion_to_bvh, read_bvh, scale_lengths
from generation.motion.kinematics import forward_kinematics, global_rotations
from generation.motion.resample import resample
from generation.motion.root import facing_directions
from generation.motion.rotations import matrix_to_quat, quat_to_matrix, yaw_matrix
from generation.motion.types import Motion, Skeleton
from measures.units import UNITS

# A rig: (joint, its parent, the Bandai-Namco joint whose motion it takes). A joint that
# takes none sits on its parent (OFFSET 0 0 0), or, given a length in cm, continues its
# parent's bone by that length (fingers); it does not rotate against its parent.
Joint = tuple[str, str | None, str | float | None]

CMU_3DSMAX: list[Joint] = [("Hips", None, "Hips")]
for _side, _s in (("Left", "L"), ("Right", "R")):
    CMU_3DSMAX += [(f"{_s}HipJoint", "Hips", None), (f"{_side}Hip", f"{_s}HipJoint", f"UpperLeg_{_s}"),
                   (f"{_side}Knee", f"{_side}Hip", f"LowerLeg_{_s}"), (f"{_side}Ankle", f"{_side}Knee", f"Foot_{_s}"),
                   (f"{_side}Toe", f"{_side}Ankle", f"Toes_{_s}")]
CMU_3DSMAX += [("lowerback", "Hips", None), ("Chest", "lowerback", "Spine"), ("Chest2", "Chest", "Chest"),
               ("lowerneck", "Chest2", None), ("Neck", "lowerneck", "Neck"), ("Head", "Neck", "Head")]
for _side, _s in (("Left", "L"), ("Right", "R")):
    CMU_3DSMAX += [(f"{_side}Collar", "Chest2", f"Shoulder_{_s}"), (f"{_side}Shoulder", f"{_side}Collar", f"UpperArm_{_s}"),
                   (f"{_side}Elbow", f"{_side}Shoulder", f"LowerArm_{_s}"), (f"{_side}Wrist", f"{_side}Elbow", f"Hand_{_s}"),
                   (f"{_s.lower()}hand", f"{_side}Wrist", None), (f"{_s}Fingers", f"{_s.lower()}hand", 7.0),
                   (f"{_s}Thumb", f"{_side}Wrist", None)]

ACCAD: list[Joint] = [("root", None, "Hips"), ("lowerback", "root", None), ("upperback", "lowerback", "Spine"),
                      ("thorax", "upperback", "Chest"), ("neck", "thorax", "Neck"), ("head", "neck", "Head")]
for _s in ("L", "R"):
    ACCAD += [(f"{_s.lower()}shoulderjoint", "thorax", f"Shoulder_{_s}"),
              (f"{_s.lower()}humerus", f"{_s.lower()}shoulderjoint", f"UpperArm_{_s}"),
              (f"{_s.lower()}radius", f"{_s.lower()}humerus", f"LowerArm_{_s}"),
              (f"{_s.lower()}hand", f"{_s.lower()}radius", f"Hand_{_s}")]
for _s in ("R", "L"):
    ACCAD += [(f"{_s.lower()}femur", "root", f"UpperLeg_{_s}"), (f"{_s.lower()}tibia", f"{_s.lower()}femur", f"LowerLeg_{_s}"),
              (f"{_s.lower()}foot", f"{_s.lower()}tibia", f"Foot_{_s}"), (f"{_s.lower()}toes", f"{_s.lower()}foot", f"Toes_{_s}")]

# A Mixamo character's rig (its "mixamorig:" names, three spine joints, finger and toe ends).
MIXAMO: list[Joint] = [("mixamorig:Hips", None, "Hips"), ("mixamorig:Spine", "mixamorig:Hips", "Spine"),
                       ("mixamorig:Spine1", "mixamorig:Spine", None), ("mixamorig:Spine2", "mixamorig:Spine1", "Chest"),
                       ("mixamorig:Neck", "mixamorig:Spine2", "Neck"), ("mixamorig:Head", "mixamorig:Neck", "Head"),
                       ("mixamorig:HeadTop_End", "mixamorig:Head", 10.0)]
for _side, _s in (("Left", "L"), ("Right", "R")):
    MIXAMO += [(f"mixamorig:{_side}Shoulder", "mixamorig:Spine2", f"Shoulder_{_s}"),
               (f"mixamorig:{_side}Arm", f"mixamorig:{_side}Shoulder", f"UpperArm_{_s}"),
               (f"mixamorig:{_side}ForeArm", f"mixamorig:{_side}Arm", f"LowerArm_{_s}"),
               (f"mixamorig:{_side}Hand", f"mixamorig:{_side}ForeArm", f"Hand_{_s}"),
               (f"mixamorig:{_side}HandMiddle1", f"mixamorig:{_side}Hand", 8.0)]
for _side, _s in (("Left", "L"), ("Right", "R")):
    MIXAMO += [(f"mixamorig:{_side}UpLeg", "mixamorig:Hips", f"UpperLeg_{_s}"),
               (f"mixamorig:{_side}Leg", f"mixamorig:{_side}UpLeg", f"LowerLeg_{_s}"),
               (f"mixamorig:{_side}Foot", f"mixamorig:{_side}Leg", f"Foot_{_s}"),
               (f"mixamorig:{_side}ToeBase", f"mixamorig:{_side}Foot", f"Toes_{_s}"),
               (f"mixamorig:{_side}Toe_End", f"mixamorig:{_side}ToeBase", 4.0)]

# CMU's rig with names that say nothing (J00, J01, ...): only its shape tells its parts.
_NAMELESS = {name: f"J{j:02d}" for j, (name, _, _) in enumerate(CMU_3DSMAX)}
NAMELESS: list[Joint] = [(_NAMELESS[name], parent and _NAMELESS[parent], source) for name, parent, source in CMU_3DSMAX]

END_SITE_CM = 5.0  # each leaf's End Site continues its bone by this much


@dataclass(frozen=True)
class Formatting:
    """How a lab's exporter writes a BVH file."""

    indent: str
    header_end: str  # line end from HIERARCHY to MOTION
    motion_end: str  # line end of the Frames and Frame Time lines and the frames
    offset_decimals: int
    position_decimals: int
    angle_decimals: int
    after_label: str  # between "Frames:" or "Frame Time:" and the number
    frame_time: str
    zero_offset: str | None = None  # how an OFFSET of zeros is written, where not as any other
    line_tail: str = ""  # before each line end


CMU_FORMAT = Formatting("\t", "\r\n", "\n", 5, 4, 4, " ", ".0083333", zero_offset="0 0 0")
METRES_FORMAT = Formatting("\t", "\n", "\n", 6, 6, 6, " ", "0.008333", line_tail=" ")
ACCAD_FORMAT = Formatting("  ", "\r\n", "\r\n", 4, 4, 2, "\t", "0.008333")


def on_rig(motion: Motion, rig: list[Joint]) -> Motion:
    """``motion`` (a Bandai-Namco take) on ``rig``, its rest pose the first frame facing +z."""
    old = motion.skeleton
    world = global_rotations(quat_to_matrix(motion.rotations), old.parents)  # (T, J, 3, 3)
    forward = facing_directions(motion.positions[:1], old)[0]
    facing = yaw_matrix(-np.arctan2(forward[0], forward[2]))  # the first frame turned to face +z
    rest_world = facing @ world[0]  # each old joint's orientation in the new rest pose

    names = [name for name, _, _ in rig]
    parents = np.array([names.index(parent) if parent else -1 for _, parent, _ in rig])
    sources = [old.index(source) if isinstance(source, str) else None for _, _, source in rig]
    rest = np.zeros((len(rig), 3))  # the new rig's rest positions, the hips at the origin
    world_new = np.zeros((motion.n_frames, len(rig), 3, 3))
    for j, (_, _, source) in enumerate(rig):
        p = parents[j]
        if sources[j] is not None:
            relative = motion.positions[0, sources[j]] - motion.positions[0, sources[0]]
            rest[j] = facing @ relative
            world_new[:, j] = world[:, sources[j]] @ rest_world[sources[j]].T
        else:
            rest[j] = rest[p] + (_bone_direction(rest, parents, p) * source if source else 0.0)
            world_new[:, j] = world_new[:, p]
    offsets = rest - np.where(parents[:, None] >= 0, rest[parents], 0.0)
    offsets[0] = 0.0
    leaves = set(range(len(rig))) - set(parents.tolist())
    end_sites = {j: (_bone_direction(rest, parents, j) * END_SITE_CM)[None] for j in sorted(leaves)}
    skeleton = Skeleton(tuple(names), parents, offsets, end_sites)

    local = world_new.copy()
    local[:, 1:] = np.swapaxes(world_new[:, parents[1:]], -1, -2) @ world_new[:, 1:]
    translations = np.broadcast_to(offsets, (motion.n_frames, len(rig), 3)).copy()
    translations[:, 0] = motion.positions[:, sources[0]]
    positions = forward_kinematics(local, translations, parents)
    return Motion(positions, motion.fps, skeleton, matrix_to_quat(local), translations)


def _bone_direction(rest: np.ndarray, parents: np.ndarray, joint: int) -> np.ndarray:
    """The unit direction of the last bone of non-zero length that ends at ``joint``."""
    while parents[joint] >= 0:
        bone = rest[joint] - rest[parents[joint]]
        if np.linalg.norm(bone) > 1e-6:
            return bone / np.linalg.norm(bone)
        joint = parents[joint]
    return np.array([0.0, 1.0, 0.0])


def lab_file_text(bvh: BVH, formatting: Formatting) -> str:
    """``bvh`` as ``formatting``'s exporter writes it."""
    f, skeleton = formatting, bvh.skeleton
    header: list[str] = ["HIERARCHY"]

    def offset(vector: np.ndarray) -> str:
        if f.zero_offset and not np.any(vector):
            return f.zero_offset
        return " ".join(f"{x:.{f.offset_decimals}f}" for x in vector)

    def joint(j: int, depth: int) -> None:
        tab = f.indent * depth
        header.extend([f"{tab}{'ROOT' if depth == 0 else 'JOINT'} {skeleton.names[j]}", f"{tab}{{",
                       f"{tab}{f.indent}OFFSET {offset(skeleton.offsets[j])}",
                       f"{tab}{f.indent}CHANNELS {len(bvh.channels[j])} {' '.join(bvh.channels[j])}"])
        for child in np.nonzero(skeleton.parents == j)[0]:
            joint(int(child), depth + 1)
        for site in skeleton.end_sites.get(j, ()):
            header.extend([f"{tab}{f.indent}End Site", f"{tab}{f.indent}{{",
                           f"{tab}{f.indent * 2}OFFSET {offset(site)}", f"{tab}{f.indent}}}"])
        header.append(f"{tab}}}")

    joint(0, 0)
    header.append("MOTION")
    decimals = [f.position_decimals if name in POSITION_AXIS else f.angle_decimals
                for names in bvh.channels for name in names]
    motion = [f"Frames:{f.after_label}{len(bvh.values)}", f"Frame Time:{f.after_label}{f.frame_time}"]
    motion += [" ".join(f"{x:.{d}f}" for x, d in zip(row, decimals)) for row in bvh.values]
    return "".join(line + f.line_tail + f.header_end for line in header) + "".join(
        line + f.line_tail + f.motion_end for line in motion)


@dataclass(frozen=True)
class LabRig:
    """A rig as a lab's files have it: its joints, rotation order, unit and formatting."""

    joints: list[Joint]
    rotation_order: str
    unit: str  # a key of measures.units.UNITS
    formatting: Formatting
    frames: int  # each take's length at 120 fps
    sources: tuple[str, ...]  # the Bandai-Namco dataset-2 takes it is written from, one a take
    rescaled_from: LabRig | None = None  # the lab file this one converts, its numbers as written there


_WALKS = ("masculine_001", "masculine_002", "masculine_003")
_CMU = LabRig(CMU_3DSMAX, "ZYX", "cmu", CMU_FORMAT, 510, _WALKS)
LAB_RIGS = {"cmu": _CMU,
            "cmu-metres": LabRig(CMU_3DSMAX, "ZYX", "m", METRES_FORMAT, 510, _WALKS, rescaled_from=_CMU),
            "accad": LabRig(ACCAD, "ZXY", "cm", ACCAD_FORMAT, 581, ("feminine_001", "feminine_002", "feminine_003"))}
LAB_FPS = 120.0
# Rigs the display figure is tried on besides those above, one take each (not folders).
MIXAMO_FORMAT = Formatting("\t", "\n", "\n", 6, 6, 6, " ", "0.008333")
FIGURE_RIGS = {"mixamo": LabRig(MIXAMO, "ZXY", "cm", MIXAMO_FORMAT, 510, _WALKS),
               "nameless": LabRig(NAMELESS, "ZYX", "cmu", CMU_FORMAT, 510, _WALKS)}


def write_lab_take(source: Path, rig: LabRig, path: Path) -> Path:
    """The Bandai-Namco take ``source`` as ``rig``'s lab would have written it at ``path``."""
    if rig.rescaled_from is not None:
        converted = read_bvh(write_lab_take(source, rig.rescaled_from, path))
        bvh = scale_lengths(converted, UNITS[rig.rescaled_from.unit] / UNITS[rig.unit])
    else:
        take = resample(read_bvh(source).to_motion(), LAB_FPS)
        take = Motion(take.positions[:rig.frames], LAB_FPS, take.skeleton, take.rotations[:rig.frames],
                      take.translations[:rig.frames])
        bvh = scale_lengths(motion_to_bvh(on_rig(take, rig.joints), rig.rotation_order), 1.0 / UNITS[rig.unit])
    path.write_bytes(lab_file_text(bvh, rig.formatting).encode())
    return path


def write_lab_folder(motion_data_2: Path, rig: LabRig, folder: Path) -> Path:
    """A lab's folder of takes on ``rig``: ``take_01.bvh``, ``take_02.bvh``, ... (three,
    so that the seeded split has one to hold out, one for validation and one to train on)."""
    folder.mkdir(parents=True, exist_ok=True)
    for k, walk in enumerate(rig.sources, start=1):
        write_lab_take(motion_data_2 / "data" / f"dataset-2_walk_{walk}.bvh", rig, folder / f"take_{k:02d}.bvh")
    return folder
