"""Another lab's motion capture made into a submission for a study's exported controls.

A lab has a folder of BVH files as its tools write them: any unit, y or z up, starting
anywhere on the floor and facing anywhere. ``prepare_submission`` takes those files and
the study's controls (``read_controls`` reads the bundle the study exports) and, in one
pass, reports per control what it matched, converted and refused; ``submission_zip`` is
then one ``ID.bvh`` per control, in centimetres with y up, at the control's frame rate
and length, starting at its start. The study's own upload runs the same function on the
files it is given, so it takes the lab's folder as it is.

Matching: a control's file is named by the control's id, ``ID.bvh``, or as ``sample``
names its clips, ``ID_NN.bvh`` (the lowest number is taken, the others are listed as left
out). ``ID.npz`` (``sample --npz``'s layout) matches as ``ID.bvh`` does, and of two files
with the same name the first by suffix is taken. A file named after no control is listed
and left out.

Units: BVH is read as every command reads it (``unit_detection``): detected from the
skeletons (all files must agree) and the first file's floor, unless ``scale`` and ``up``
are given. An ``.npz`` holds centimetres with y up by its layout. A body that is not
MIN_HEIGHT_CM to MAX_HEIGHT_CM tall once read is refused: the unit was not centimetres.

Alignment: the clip's root is measured where the study measures it, on the clip as the
study keeps it (resampled to the control's frame rate, its first frames): the hips
projected on the floor and smoothed, facing the way the left/right joints say
(``root.root_trajectory``). The whole clip is then moved along the floor and turned about
the vertical so that at its first frame this root stands at the control's start, the
origin, facing +z. That is a rigid motion on the floor: heights, bone lengths and the
motion itself are unchanged. With ``align=False`` the clip stays where it is. For a path
control the largest distance of the root from the control's path is reported, and a clip
farther than the study's tolerance is refused.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import zipfile
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from .control import Control, PathControl, control_from_dict
from .motion.bvh import BVH, BVHError, bvh_text, motion_to_bvh, read_bvh
from .motion.kinematics import subtree_motion
from .motion.npz import load_motion_npz
from .motion.resample import resample
from .motion.root import RootOptions, hips_index, root_trajectory
from .motion.rotations import matrix_to_quat, quat_to_matrix, yaw_matrix
from .motion.types import Motion
from .motion.unit_detection import choose_units

# Sampled models follow a commanded path loosely; a root farther than this has not followed it.
PATH_TOLERANCE_CM = 100.0
# A person is 50-250 cm tall: a clip read in the wrong unit (metres, millimetres) is outside.
MIN_HEIGHT_CM, MAX_HEIGHT_CM = 50.0, 250.0
MOTION_SUFFIXES = (".bvh", ".npz")
# How ``sample`` names the clips of a control: the control's name, "_", a sample number.
NUMBERED = re.compile(r"(?P<id>.+)[_-](?P<number>\d+)")


@dataclass(frozen=True)
class ControlResult:
    """What became of one control: the file it matched (None: none did), the motion
    ready to submit (None: refused), what was done to it and why it was refused."""

    control: str
    file: Path | None
    motion: Motion | None
    converted: tuple[str, ...] = ()
    refused: str = ""
    left_out: tuple[Path, ...] = ()  # other files that matched the control
    source_fps: float | None = None  # the frame rate the file has (the motion is at its control's)

    def line(self) -> str:
        name = self.file.name if self.file else "no file"
        others = f" (left out: {', '.join(p.name for p in self.left_out)})" if self.left_out else ""
        outcome = f"refused: {self.refused}" if self.refused else "; ".join(self.converted)
        return f"{self.control}: {name}{others}: {outcome}"


@dataclass(frozen=True)
class SubmissionReport:
    """Every control's result, the units the files were read in, and the files that
    matched no control."""

    units: str
    results: tuple[ControlResult, ...]
    unmatched: tuple[Path, ...]

    @property
    def accepted(self) -> bool:
        return all(result.motion is not None for result in self.results)

    def lines(self) -> list[str]:
        lines = [self.units, *(result.line() for result in self.results)]
        if self.unmatched:
            lines.append(f"named after no control, left out: {', '.join(p.name for p in self.unmatched)}")
        refused = sum(result.motion is None for result in self.results)
        lines.append(f"{len(self.results) - refused} of {len(self.results)} controls ready"
                     + (f", {refused} refused: nothing written" if refused else ""))
        return lines

    def refused_lines(self) -> list[str]:
        """Those of ``lines`` that say what was refused: each refused control's, and the count's
        where any was (the others say what was read and what was ready)."""
        refused = [result.line() for result in self.results if result.motion is None]
        return refused + self.lines()[-1:] if refused else []


def read_controls(bundle: str | os.PathLike) -> dict[str, Control]:
    """The controls of a study's exported bundle (a folder or its zip) by id, in the
    order of its ``index.json``; ValueError naming the bundle and what is wrong."""
    bundle = Path(bundle)
    try:
        files = _bundle_files(bundle)
        index = json.loads(files["index.json"])
        controls = {}
        for entry in index["controls"]:
            ident, file = str(entry["id"]), str(entry["file"])
            if PurePosixPath(ident).name != ident or ident.startswith("."):
                raise ValueError(f"the control id {ident!r} is not a plain file name")
            if file not in files:
                raise ValueError(f"control {ident!r}: its file {file} is missing")
            controls[ident] = _read_control(ident, file, files[file])
    except KeyError as error:
        raise ValueError(f"{bundle}: not a controls bundle exported by the study (no {error} in it)") from None
    except (ValueError, TypeError, OSError, zipfile.BadZipFile) as error:
        raise ValueError(f"{bundle}: {error}") from None
    if not controls:
        raise ValueError(f"{bundle}: the bundle lists no controls")
    return controls


def _bundle_files(bundle: Path) -> dict[str, bytes]:
    """The bundle's files by path relative to its index.json (a zip has them under a folder)."""
    if bundle.is_dir():
        return {str(p.relative_to(bundle).as_posix()): p.read_bytes() for p in bundle.rglob("*") if p.is_file()}
    with zipfile.ZipFile(bundle) as archive:
        names = [name for name in archive.namelist() if not name.endswith("/")]
        index = min((name for name in names if PurePosixPath(name).name == "index.json"), key=len, default=None)
        if index is None:
            raise KeyError("index.json")
        prefix = index[: -len("index.json")]
        return {name[len(prefix):]: archive.read(name) for name in names if name.startswith(prefix)}


def _read_control(ident: str, file: str, data: bytes) -> Control:
    if file.endswith(".json"):
        return control_from_dict(json.loads(data))
    with np.load(io.BytesIO(data), allow_pickle=False) as arrays:
        lead_in = arrays["lead_in"] if "lead_in" in arrays.files else None
        return PathControl(arrays["velocities"], float(arrays["fps"]), ident, lead_in)


def match_files(files: Sequence[Path], ids: Sequence[str]) -> tuple[dict[str, list[Path]], list[Path]]:
    """The files that match each control id, the chosen one first (``ID.bvh``, then
    ``ID.npz``, else the lowest ``ID_NN.bvh``), and the files that match none."""
    matched: dict[str, list[Path]] = {ident: [] for ident in ids}
    numbered = []
    for path in sorted(files, key=lambda p: (MOTION_SUFFIXES.index(p.suffix.lower())
                                             if p.suffix.lower() in MOTION_SUFFIXES else len(MOTION_SUFFIXES))):
        found = NUMBERED.fullmatch(path.stem)
        if path.stem in matched:
            matched[path.stem].append(path)
        elif found and found["id"] in matched:
            numbered.append((found["id"], int(found["number"]), path))
    for ident, _, path in sorted(numbered, key=lambda item: item[:2]):
        matched[ident].append(path)
    taken = {path for paths in matched.values() for path in paths}
    return matched, [path for path in files if path not in taken]


def prepare_submission(files: Sequence[str | os.PathLike], controls: Mapping[str, Control],
                       scale: float | None = None, up: str | None = None, root: RootOptions = RootOptions(),
                       align: bool = True, path_tolerance_cm: float = PATH_TOLERANCE_CM) -> SubmissionReport:
    """Match, convert and check a lab's BVH ``files`` for the study's ``controls`` (by id).

    Units of BVH files are detected unless ``scale`` (file units to cm) and ``up`` are
    given; ``.npz`` files are centimetres with y up. ``root`` says how the study finds the
    root (its checkpoints' ``RootOptions``). Refusals are per control; a folder whose BVH
    files mix units is a ValueError, as for every command.
    """
    files = [Path(f) for f in files]
    matched, unmatched = match_files(files, list(controls))
    chosen = {ident: paths[0] for ident, paths in matched.items() if paths}
    readable: dict[str, BVH | Motion] = {}
    results = {}
    for ident, path in chosen.items():
        try:
            readable[ident] = load_motion_npz(path) if path.suffix.lower() == ".npz" else read_bvh(path)
        except (BVHError, ValueError) as error:
            results[ident] = ControlResult(ident, path, None, refused=f"unreadable ({error})",
                                           left_out=tuple(matched[ident][1:]))
    bvh_files = [chosen[ident] for ident, read in readable.items() if isinstance(read, BVH)]
    units = choose_units(bvh_files, scale, up, root) if bvh_files else None
    skeletons = {}
    for ident, read in readable.items():
        if isinstance(read, BVH):
            motion, read_as = read.to_motion(units.units.scale, units.units.up), f"read as {units.units.describe()}"
        else:
            motion, read_as = read, "read as centimetres, y up (.npz)"
        skeletons[ident] = (motion.skeleton.names, tuple(motion.skeleton.parents))
        clip, steps, refused = _convert(motion, controls[ident], root, align, path_tolerance_cm)
        results[ident] = ControlResult(ident, chosen[ident], clip, (read_as, *steps), refused,
                                       tuple(matched[ident][1:]), motion.fps)
    for ident in controls:
        if ident not in results:
            results[ident] = ControlResult(ident, None, None, refused=f"no file named {ident}.bvh or {ident}_NN.bvh")
    ordered = _one_skeleton([results[ident] for ident in controls], skeletons)
    described = units.description if units else "motion units: no BVH file was read"
    return SubmissionReport(described, tuple(ordered), tuple(unmatched))


def _convert(motion: Motion, control: Control, root: RootOptions, align: bool,
             tolerance: float) -> tuple[Motion | None, list[str], str]:
    """The motion as submitted for the control and what was done to it, or why it is refused."""
    if motion.fps + 1e-6 < control.fps:
        return None, [], (f"{motion.fps:g} fps is below the control's {control.fps:g} fps; motion is resampled "
                          "down, never up")
    clip = resample(motion, control.fps)
    if clip.n_frames < control.n_frames:
        return None, [], (f"{clip.n_frames} frames ({clip.n_frames / control.fps:.2f} s) at {control.fps:g} fps, "
                          f"shorter than its control's {control.n_frames} frames "
                          f"({control.n_frames / control.fps:.2f} s)")
    steps = [f"resampled from {motion.fps:g} to {control.fps:g} fps"] if motion.fps != control.fps else []
    steps.append(f"its first {control.n_frames} of {clip.n_frames} frames ({control.n_frames / control.fps:g} s)")
    clip = _first_frames(clip, control.n_frames)
    try:
        body = _body(clip, root)
        start = root_trajectory(body, root)
    except ValueError as error:
        return None, [], str(error)
    height = body_height(body)
    if not MIN_HEIGHT_CM <= height <= MAX_HEIGHT_CM:
        return None, steps, (f"the body is {height:.3g} cm tall as read; a body is {MIN_HEIGHT_CM:g}-"
                             f"{MAX_HEIGHT_CM:g} cm tall: give the files' unit (BVH) or write centimetres (.npz)")
    if align:
        shift, turn = -start.xz[0], -float(start.yaw[0])
        clip = moved_on_floor(clip, shift, turn)
        steps.append(f"moved {np.linalg.norm(shift) / 100:.2f} m and turned {round(math.degrees(turn)):+d} degrees to "
                     "start at the origin facing +z")
        start = root_trajectory(_body(clip, root), root)
    else:
        steps.append("left where it is")
    if isinstance(control, PathControl):
        distance = np.linalg.norm(start.xz - control.path().xz, axis=1)
        worst = int(distance.argmax())
        if distance[worst] > tolerance:
            return None, steps, (f"the root strays {distance[worst]:.0f} cm from the control's path (at frame "
                                 f"{worst}); the tolerance is {tolerance:g} cm")
        steps.append(f"its root at most {distance[worst]:.0f} cm from the path (the tolerance is {tolerance:g} cm)")
    return clip, steps, ""


def _body(motion: Motion, options: RootOptions) -> Motion:
    """The body, the hips and below, where the study measures the root (as the models' data does)."""
    return subtree_motion(motion, hips_index(motion.skeleton, options.hips))


def body_height(motion: Motion) -> float:
    """The largest vertical extent of the body over the clip (about a person's height when standing)."""
    y = motion.positions[..., 1]
    return float((y.max(axis=1) - y.min(axis=1)).max())


def _first_frames(motion: Motion, frames: int) -> Motion:
    if motion.rotations is None:
        return Motion(motion.positions[:frames], motion.fps, motion.skeleton)
    return Motion(motion.positions[:frames], motion.fps, motion.skeleton, motion.rotations[:frames],
                  motion.translations[:frames])


def moved_on_floor(motion: Motion, shift_xz: np.ndarray, turn: float) -> Motion:
    """The motion shifted by ``shift_xz`` (x, z) on the floor, then turned by ``turn``
    radians about the vertical through the origin (left positive, as yaw)."""
    turning = yaw_matrix(turn)
    shift = np.array([shift_xz[0], 0.0, shift_xz[1]])
    positions = (motion.positions + shift) @ turning.T
    if motion.rotations is None:
        return Motion(positions, motion.fps, motion.skeleton)
    rotations, translations = motion.rotations.copy(), motion.translations.copy()
    rotations[:, 0] = matrix_to_quat(turning @ quat_to_matrix(rotations[:, 0]))
    translations[:, 0] = (translations[:, 0] + shift) @ turning.T
    return Motion(positions, motion.fps, motion.skeleton, rotations, translations)


def _one_skeleton(results: list[ControlResult], skeletons: dict[str, tuple]) -> list[ControlResult]:
    """The results with clips on another skeleton (joint names and parents) than most
    files read have refused: a submission is one skeleton."""
    if not skeletons:
        return results
    common, _ = Counter(skeletons.values()).most_common(1)[0]
    example = next(r for r in results if skeletons.get(r.control) == common)
    return [ControlResult(r.control, r.file, None, (), f"its skeleton ({len(skeletons[r.control][0])} joints) differs "
                          f"from the one of {example.file.name} ({len(common[0])} joints)", r.left_out)
            if r.motion and skeletons[r.control] != common else r for r in results]


def submission_zip(report: SubmissionReport) -> bytes:
    """The accepted clips as the study's upload reads them: ``ID.bvh`` per control, in
    centimetres with y up. ValueError where a control was refused."""
    if not report.accepted:
        refused = [r.control for r in report.results if r.motion is None]
        raise ValueError(f"{len(refused)} control(s) refused ({', '.join(refused)}): no submission written")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for result in report.results:
            archive.writestr(f"{result.control}.bvh", bvh_text(motion_to_bvh(result.motion)))
    return buffer.getvalue()
