"""Reading generated or natural motion for the objective metrics: a small npz layout.

One ``.npz`` file holds one clip or a stack of equal-length clips of one system:

==========  ======================  ===============================================
key         shape / type            meaning
==========  ======================  ===============================================
positions   (frames, joints, 3) or  joint positions in cm, y up
            (clips, frames, joints,
            3) float
fps         scalar                  frames per second
names       (joints,) str           joint names
parents     (joints,) int           parent index per joint, -1 for the root
offsets     (joints, 3) float       rest offsets from the parent in cm; optional,
                                    without them no bone-length error is computed
system      scalar str              optional; the system the clips belong to
==========  ======================  ===============================================

For the control-adherence metrics (`analysis.reports.adherence`) a clip made for a path control
also carries, all four or none, per frame (a stack: with the clips' axis first):

============  ============  ====================================================
key           shape         meaning
============  ============  ====================================================
control_path  (frames, 2)   the floor path (x, z) in cm the clip was asked to follow
control_yaw   (frames,)     the facing it asks for, radians, 0 facing +z, left positive
root_path     (frames, 2)   where the clip's root went on the floor, cm
root_yaw      (frames,)     the root's facing, radians
============  ============  ====================================================

Both in the clip's own floor coordinates (a y-up floor in cm, whatever unit the positions
are in). The root is the models' (`generation.motion.root`: the hips' floor projection and
facing, smoothed), which ``python -m generation sample`` and ``natural`` write beside every
clip of a path control.

Without a ``system`` key the system is named by where the file lies: a file given
directly, or lying directly in a given folder, is named by its stem (``MoGlow.npz``);
a file in a subfolder of a given folder by that subfolder (``DIR/MoGlow/clip_001.npz``).
All files of one system must share fps, joint names and parents.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.errors import AnalysisInputError


FOLLOWING_KEYS = ("control_path", "control_yaw", "root_path", "root_yaw")


@dataclass(frozen=True)
class FollowedPath:
    """A clip's control path and its root's path, for the control-adherence metrics."""

    control_xz: np.ndarray  # (frames, 2) cm
    control_yaw: np.ndarray  # (frames,) radians
    root_xz: np.ndarray
    root_yaw: np.ndarray


@dataclass
class SystemClips:
    """All clips of one system on one skeleton."""

    system: str
    fps: float
    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray | None
    clips: list[np.ndarray] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)  # the file of each clip, for messages
    followed: list[FollowedPath | None] = field(default_factory=list)  # per clip read from files; None: no control

    def source(self, k: int) -> str:
        """Where clip ``k`` came from: its file (``FILE[i]`` in a stack of clips), or its
        place in the system where the clips were not read from files."""
        return self.sources[k] if k < len(self.sources) else f"clip {k + 1} of {self.system}"


def save_clips(path: str | os.PathLike, positions: np.ndarray, fps: float, names, parents,
               offsets: np.ndarray | None = None, system: str | None = None) -> Path:
    """Write clips in the layout above (the inverse of `load_motion_sets` for one file)."""
    arrays = {"positions": np.asarray(positions, dtype=np.float32), "fps": np.float64(fps),
              "names": np.asarray(names, dtype=str), "parents": np.asarray(parents, dtype=np.int64)}
    if offsets is not None:
        arrays["offsets"] = np.asarray(offsets, dtype=np.float64)
    if system is not None:
        arrays["system"] = np.asarray(system)
    path = Path(path)
    np.savez_compressed(path, **arrays)
    return path


def load_motion_sets(paths: list[str | os.PathLike]) -> dict[str, SystemClips]:
    """Read npz files and folders of them into clips grouped by system."""
    systems: dict[str, SystemClips] = {}
    for given in map(Path, paths):
        if given.is_dir():
            files = sorted(given.rglob("*.npz"))
            if not files:
                raise AnalysisInputError(f"no .npz motion files under {given}")
            named = [(f, f.stem if f.parent == given else f.relative_to(given).parts[0]) for f in files]
        elif given.is_file():
            named = [(given, given.stem)]
        else:
            raise AnalysisInputError(f"motion path {given} does not exist")
        for file, default_name in named:
            _add_file(systems, file, default_name)
    return systems


def _add_file(systems: dict[str, SystemClips], file: Path, default_name: str) -> None:
    try:
        data = np.load(file, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise AnalysisInputError(f"{file}: not a readable npz file ({exc})") from exc
    missing = [k for k in ("positions", "fps", "names", "parents") if k not in data.files]
    if missing:
        raise AnalysisInputError(f"{file}: lacks {', '.join(missing)} (see analysis/motion/motion_io.py)")
    try:
        positions = np.asarray(data["positions"], dtype=np.float64)
        names = tuple(str(n) for n in np.atleast_1d(data["names"]))
        parents = np.asarray(data["parents"], dtype=np.int64)
        fps = float(data["fps"])
    except (TypeError, ValueError) as exc:
        raise AnalysisInputError(f"{file}: positions, fps, names or parents of the wrong type ({exc})") from None
    if not (np.isfinite(fps) and fps > 0):
        raise AnalysisInputError(f"{file}: fps must be a positive number, got {fps}")
    if parents.shape != (len(names),) or any(not -1 <= p < j for j, p in enumerate(parents)):
        raise AnalysisInputError(f"{file}: parents must give each of the {len(names)} joints an earlier joint "
                                 "or -1 for the root")
    if positions.ndim == 3:
        positions = positions[None]
    if positions.ndim != 4 or positions.shape[2:] != (len(names), 3):
        raise AnalysisInputError(
            f"{file}: positions must be (frames, {len(names)}, 3) or (clips, frames, "
            f"{len(names)}, 3), got {data['positions'].shape}"
        )
    if not np.isfinite(positions).all():
        raise AnalysisInputError(f"{file}: positions contain NaN or infinity")
    system = str(data["system"]) if "system" in data.files else default_name
    offsets = np.asarray(data["offsets"], dtype=np.float64) if "offsets" in data.files else None
    entry = systems.setdefault(system, SystemClips(system, fps, names, parents, offsets))
    if entry.fps != fps or entry.names != names or not np.array_equal(entry.parents, parents):
        raise AnalysisInputError(
            f"{file}: fps or skeleton differ from earlier files of system {system!r}"
        )
    entry.followed.extend(_followed_paths(data, file, positions.shape[:2]))
    entry.clips.extend(positions)
    entry.sources.extend([str(file)] if len(positions) == 1 else [f"{file}[{k}]" for k in range(len(positions))])


def _followed_paths(data, file: Path, shape: tuple[int, int]) -> list[FollowedPath | None]:
    """The control and root paths of each of a file's ``shape`` = (clips, frames), or Nones."""
    present = [key for key in FOLLOWING_KEYS if key in data.files]
    if not present:
        return [None] * shape[0]
    if len(present) < len(FOLLOWING_KEYS):
        missing = ", ".join(k for k in FOLLOWING_KEYS if k not in present)
        raise AnalysisInputError(f"{file}: has {', '.join(present)} but not {missing}; the control-adherence "
                                 "metrics read all four (see analysis/motion/motion_io.py)")
    arrays = {}
    for key in FOLLOWING_KEYS:
        try:
            value = np.asarray(data[key], dtype=np.float64)
        except (TypeError, ValueError):
            raise AnalysisInputError(f"{file}: {key} must hold numbers") from None
        wanted = (*shape, 2) if key.endswith("path") else shape
        if value.shape == wanted[1:]:
            value = value[None]
        if value.shape != wanted:
            raise AnalysisInputError(f"{file}: {key} must be {wanted[1:]} for positions of {shape[1]} frames "
                                     f"(or {wanted} for a stack), got {data[key].shape}")
        if not np.isfinite(value).all():
            raise AnalysisInputError(f"{file}: {key} contains NaN or infinity")
        arrays[key] = value
    return [FollowedPath(*(arrays[key][k] for key in FOLLOWING_KEYS)) for k in range(shape[0])]
