"""A study's motion as the objective metrics and animation tools read it: one folder per
system, one clip in two files.

    OUT/<system>/<control id>.npz    positions (frames, joints, 3) cm, y up; fps; names;
                                     parents; offsets; system (analysis/motion/motion_io.py's layout);
                                     for a path control also control_path, control_yaw,
                                     root_path and root_yaw (its control adherence)
    OUT/<system>/<control id>.bvh    the same clip as a rotation BVH on the system's rig:
                                     every joint's ZXY rotation and the root's position,
                                     in cm with y up (BVH cannot say so itself)
    OUT/<system>/<control id>.json   for a label control, the labels it asked for
                                     ({"content": action, "style": style}: the BVH
                                     reader's label side file)

The BVH files hold rotations for every kind of system, so the motion loads onto a
character in Blender, Maya or a game engine: NAT's are the capture's own; every other
clip is kept as positions (sampled motion of any model kind, submitted motion), and its
rotations are those that inverse kinematics finds on the rig (``generation.motion.ik``:
the rig's bone lengths, every bone pointing where the clip's does; a label model's
clip, made by its rig's forward kinematics, comes back joint for joint). The objective
metrics read the ``.npz`` files only. A label model's adherence is how often HVRNN's
attribute classifiers see the asked labels in its clips: ``python -m generation
hvrnn-label OUT/<system> --classifiers FILE --out labels.csv`` lists what they see beside
the side files' labels and says how often they agree.

Systems are named as in the ratings table (``System.export_name``: NAT and BAD for those
roles, a model system by its name), in each file's ``system`` array and, where the name
is a plain file name, in its folder's name (else ``system-<id>``), so ``python -m analysis objective OUT --out DIR`` and
``python -m analysis report RATINGS.csv --motion OUT`` put each system's metrics beside
its ratings. A clip is the motion of a finished stimulus as its system's source gives it
to the renderer (``sources``): a checkpoint's sampled motion, submitted motion, the
natural clip; uploaded videos have no motion and are left out. A clip sampled with
another seed than 0 is ``<control id>-seed<seed>.npz`` (and ``.bvh``).

The folder is written under a temporary name beside ``out`` and renamed into place, so a
failure leaves nothing behind. ``motion_zip`` gives the same files as a zip.
"""

from __future__ import annotations

import io
import json
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from generation.control import AttributeControl, PathControl, following_arrays
from generation.files import atomic_folder, write_atomic
from generation.motion.bvh import bvh_text, motion_to_bvh
from generation.motion.npz import save_motion_npz
from generation.motion.root import RootTrajectory
from generation.motion.types import Motion
from studyapp.models import Stimulus, Study, System
from studyapp.stimuli.control_export import SAFE_ID, control_id
from studyapp.stimuli.controls import study_options
from studyapp.stimuli.sources import Clip, source_of


def folder_name(system: System) -> str:
    """A system's folder: its exported name where that is a plain file name (no path can
    come of a system's name)."""
    return system.export_name if SAFE_ID.fullmatch(system.export_name) else f"system-{system.pk}"


def clip_name(stimulus: Stimulus) -> str:
    """The name of a stimulus's files inside its system's folder, without their suffix."""
    name = control_id(stimulus.control)
    return name if stimulus.seed == 0 else f"{name}-seed{stimulus.seed}"


def exported_stimuli(study: Study) -> list[Stimulus]:
    """The finished stimuli that have motion (every one but uploaded videos'), each clip
    once: an appropriateness study's mismatched clips are the motion of another one."""
    return list(study.stimuli.filter(status=Stimulus.Status.DONE, control__isnull=False, shown_control__isnull=True)
                .select_related("study", "system", "control").order_by("system__name", "control__name", "seed"))


def adherence_arrays(stimulus: Stimulus, clip: Clip) -> dict[str, np.ndarray]:
    """For a clip of a path control, the arrays the control-adherence metrics read
    (``generation.control.following_arrays``): the path it was asked to follow and where
    its root went, in the frame where every control's path starts (natural motion moved
    there); none for a label control."""
    signal = stimulus.control.signal()
    if not isinstance(signal, PathControl):
        return {}
    root = study_options(stimulus.study).root
    motion = clip.on_control_path(signal.n_frames, root)
    asked = signal.path()
    frames = motion.n_frames
    return following_arrays(motion, RootTrajectory(asked.xz[:frames], asked.yaw[:frames]), root)


def label_side_file(stimulus: Stimulus) -> bytes | None:
    """For a clip of a label control, the labels it asked for as the BVH reader's side
    file reads them (``generation.motion.clip_files.read_labels``); None for a path."""
    signal = stimulus.control.signal()
    if not isinstance(signal, AttributeControl):
        return None
    return json.dumps({"content": signal.action, "style": signal.style}).encode()


def first_frames(motion: Motion, frames: int) -> Motion:
    """The first ``frames`` of a motion, its rotations with them (a natural take can run a
    frame past its control, whose arrays lie beside it)."""
    cut = slice(0, frames)
    return Motion(motion.positions[cut], motion.fps, motion.skeleton,
                  None if motion.rotations is None else motion.rotations[cut],
                  None if motion.translations is None else motion.translations[cut])


def write_motion(study: Study, out: Path) -> dict[str, int]:
    """Write the motion of every finished stimulus of ``study`` into the new or empty folder
    ``out``; how many clips each system got, by the system's exported name."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: give a new or empty folder")
    counts: dict[str, int] = {}
    with atomic_folder(out) as work:
        for stimulus in exported_stimuli(study):
            system = stimulus.system.export_name
            try:
                clip = source_of(stimulus.system).clip(stimulus)
            except (ValueError, FileNotFoundError) as error:
                raise ValueError(f"the motion of {stimulus.system.name} for {stimulus.control.name}: {error}") from None
            following = adherence_arrays(stimulus, clip)
            motion = first_frames(clip.motion, len(following["root_yaw"]) if following else clip.motion.n_frames)
            folder, name = work / folder_name(stimulus.system), clip_name(stimulus)  # a name may hold a dot: "-2.5s"
            save_motion_npz(motion, folder / f"{name}.npz", system=np.array(system), **following)
            write_atomic(folder / f"{name}.bvh", bvh_text(motion_to_bvh(motion)).encode())
            if (labels := label_side_file(stimulus)) is not None:
                write_atomic(folder / f"{name}.json", labels)
            counts[system] = counts.get(system, 0) + 1
    return counts


def motion_zip(study: Study) -> bytes:
    """The same folder as a zip, under ``motion-study-<pk>/`` (the monitor's download)."""
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch) / f"motion-study-{study.pk}"
        write_motion(study, folder)
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(p for p in folder.rglob("*") if p.is_file()):
                archive.write(path, path.relative_to(folder.parent).as_posix())
        return buffer.getvalue()


__all__ = ["adherence_arrays", "clip_name", "exported_stimuli", "folder_name", "motion_zip", "write_motion"]
