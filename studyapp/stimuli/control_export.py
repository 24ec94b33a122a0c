"""A study's controls as files any code can read, for labs that make motion elsewhere.

The bundle (a folder, or the same files in a zip):

    README.txt          what the files hold and what a submission must look like
    index.json          the study's controls: id, origin, frames, fps, seconds, file
    paths/ID.npz        a path control (see PATH_ARRAYS)
    labels/ID.json      a label control: action, style, frames, fps
    natural/ID.bvh      optionally, the natural clip of a held-out control, placed in the
                        control's frame: a valid submission for that control (in
                        centimetres with y up, which the README and index.json say)

A control's id is the name it was created with where that is a plain file name, else
``control-<pk>``, and renaming the control keeps it; submitted files are named by it
(``studyapp.stimuli.submissions``).
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from generation import registry
from generation.control import PathControl
from generation.motion.bvh import bvh_text, motion_to_bvh
from generation.motion.root import root_trajectory, to_root_frame
from generation.motion.types import Motion
from generation.submission import MAX_HEIGHT_CM, MIN_HEIGHT_CM
from studyapp.models import SAFE_ID, ControlSignal, Study
from studyapp.stimuli.controls import natural_options, study_options
from studyapp.stimuli.natural import natural_motion


UNITS = {"forward": "cm/s", "sideways": "cm/s, left positive", "yaw_velocity": "rad/s, counter-clockwise seen from above (left turn) positive",
         "root_path": "cm, (x, z) on the floor", "root_yaw": "rad, 0 faces +z", "fps": "frames per second",
         "natural": "BVH lengths (OFFSET, End Site, position channels) in cm, y up; angles in degrees"}
AXES = ("y up; the floor is the x-z plane; every path starts at the origin facing +z; forward and sideways "
        "velocities are in the character's root frame at the previous frame")

PATH_ARRAYS = """\
  velocities    (frames, 3) float64: forward, sideways, yaw_velocity per frame, as below
  forward       (frames,) cm/s, along the direction the character faces
  sideways      (frames,) cm/s, to the character's left positive
  yaw_velocity  (frames,) rad/s, turning left positive
  root_path     (frames, 2) cm: the path integrated from the velocities, (x, z) on the floor
  root_yaw      (frames,) rad: the facing along it (0 = +z)
  fps           scalar: frames per second
  frames        scalar: number of frames
  lead_in       (lead, 3) float64, only in a held-out control that starts part-way into its
                take: the take's velocities before the clip, as above, for a model to warm
                up on; the motion submitted covers the `frames` after it"""

SUBMISSION_RULES = """\
A submission is one file per control, named by the control's id (the "id" of index.json):
ID.bvh or ID.npz, or ID_NN.bvh as `python -m generation sample` names its clips (the
lowest NN is taken, the others are listed as left out), in a folder or a zip (folders
inside the zip are ignored; only the file names count). Every control of index.json
needs a file; a file named after no control is listed and left out.

Motion files:
  ID.bvh   any BVH file as your tools write it: any length unit, y or z up, starting
           anywhere on the floor and facing anywhere. The unit and the up axis are
           detected from the files (all must agree), or given on upload.
  ID.npz   positions (frames, joints, 3) float, centimetres, y up; fps (scalar); names
           (joints,) strings; parents (joints,) integers, -1 for the root; optionally
           offsets (joints, 3). This is the layout `python -m generation sample --npz` writes.

What the study does with each file, reporting per control what it matched, converted
and refused (every problem is listed at once; nothing is stored unless every control
has its clip):
  - it reads the file in its unit and up axis, into centimetres with y up;
  - it resamples it to the control's fps (down only: the frame rate must be at least
    the control's) and keeps its first `frames` frames (a shorter clip is refused);
  - it moves the clip along the floor and turns it about the vertical so that its root
    (the hips projected on the floor, smoothed over {sigma:g} s, facing the way the left
    and right joints say) starts where root_path does: at the origin, facing +z. Heights,
    bone lengths and the motion itself are unchanged. On upload, "keep the root where
    it is" leaves the clip where it was captured;
  - for path controls, it refuses a root more than {tolerance:g} cm from root_path at
    some frame (the largest distance is reported);
  - it refuses a body that is not {min_height:g}-{max_height:g} cm tall as read (a unit
    not detected right: give it), values that are not finite, and files on another
    skeleton (joint names and parents) than most of them.

The same rules run before you upload with
`python -m generation prepare-submission FOLDER --controls THIS_BUNDLE -o submission.zip`.
The study renders accepted motion with its own renderer, camera, length and video size,
exactly as it renders the motion it samples itself.
"""


def control_id(control: ControlSignal) -> str:
    """The file name stem of a control in an export and in a submission: its export id,
    which a rename leaves as it was."""
    return control.export_id or f"control-{control.pk}"


def natural_in_control_frame(motion: Motion, root_options) -> Motion:
    """The natural clip moved so that its root starts at the origin facing +z, as its
    control's path does."""
    root = root_trajectory(motion, root_options)
    positions = motion.positions.copy()
    floor = to_root_frame(positions[..., [0, 2]] - root.xz[0], root.yaw[0])
    positions[..., 0], positions[..., 2] = floor[..., 0], floor[..., 1]
    return Motion(positions, motion.fps, motion.skeleton)


def _path_npz(control: PathControl) -> bytes:
    path = control.path()
    buffer = io.BytesIO()
    v = control.velocities
    lead_in = {} if control.lead_in is None else {"lead_in": control.lead_in}
    np.savez(buffer, velocities=v, forward=v[:, 0], sideways=v[:, 1], yaw_velocity=v[:, 2], root_path=path.xz,
             root_yaw=path.yaw, fps=np.float64(control.fps), frames=np.int64(control.n_frames), **lead_in)
    return buffer.getvalue()


def _readme(study: Study, kind: str) -> str:
    sigma = study_options(study).root.position_sigma
    controls = ("paths/ID.npz, one per path control, with these arrays:\n" + PATH_ARRAYS if kind == registry.PATH else
                "labels/ID.json, one per label control: action, style, frames, fps")
    return (f"Controls of the study \"{study.title}\"\n\nUnits and axes: {AXES}.\n\n"
            f"index.json lists every control (id, name, origin, frames, fps, seconds, its file, the seconds\n"
            f"of its take before it (lead_in_seconds) where it has a lead-in and, when exported, its\n"
            f"natural clip). The controls are in\n{controls}\n\n"
            "natural/ID.bvh (when exported) is the natural motion of a held-out control, in the control's\n"
            "frame and at its frame rate: an example of a valid submission file. Its lengths (OFFSET, End\n"
            "Site and position channels) are in centimetres with y up: BVH has no field to say so.\n\n"
            + SUBMISSION_RULES.format(min_height=MIN_HEIGHT_CM, max_height=MAX_HEIGHT_CM, sigma=sigma,
                                      tolerance=study.path_tolerance_cm))


def bundle_files(study: Study, natural: bool = False) -> dict[str, bytes]:
    """The bundle's files by relative path."""
    controls = list(study.controls.all())
    if not controls:
        raise ValueError(f"the study {study.title!r} has no controls to export")
    files: dict[str, bytes] = {}
    entries = []
    kinds = set()
    for control in controls:
        signal = control.signal()
        ident = control_id(control)
        entry = {"id": ident, "name": control.name, "origin": control.origin, "frames": signal.n_frames,
                 "fps": signal.fps, "seconds": control.seconds}
        if control.lead_in_seconds:
            entry["lead_in_seconds"] = control.lead_in_seconds
        if isinstance(signal, PathControl):
            kinds.add(registry.PATH)
            entry["file"] = f"paths/{ident}.npz"
            files[entry["file"]] = _path_npz(signal)
        else:
            kinds.add(registry.LABELS)
            entry["file"] = f"labels/{ident}.json"
            files[entry["file"]] = json.dumps({"id": ident, **signal.to_dict()}, indent=2).encode()
        if natural and control.origin == ControlSignal.Origin.HELD_OUT and control.source_clip:
            entry["natural"] = f"natural/{ident}.bvh"
            files[entry["natural"]] = _natural_bvh(control).encode()
        entries.append(entry)
    kind = registry.PATH if kinds == {registry.PATH} else registry.LABELS
    index = {"study": study.title, "kind": kind, "units": UNITS, "axes": AXES, "controls": entries}
    files["index.json"] = json.dumps(index, indent=2).encode()
    files["README.txt"] = _readme(study, kind).encode()
    return files


def _natural_bvh(control: ControlSignal) -> str:
    options = natural_options(control)
    motion = natural_motion(control, options)
    return bvh_text(motion_to_bvh(natural_in_control_frame(motion, options.root)))


def write_bundle(study: Study, out: Path, natural: bool = False) -> list[Path]:
    """Write the bundle into the folder ``out`` (created); the files written."""
    written = []
    for relative, data in bundle_files(study, natural).items():
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        written.append(path)
    return written


def bundle_zip(study: Study, natural: bool = False) -> bytes:
    """The bundle as a zip, every file under ``controls-study-<pk>/``."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for relative, data in bundle_files(study, natural).items():
            archive.writestr(f"controls-study-{study.pk}/{relative}", data)
    return buffer.getvalue()


__all__ = ["AXES", "SAFE_ID", "bundle_files", "bundle_zip", "control_id", "natural_in_control_frame", "write_bundle"]
