"""Which BVH files a motion folder holds and what each shows: the folders (one, or several
pooled), the files in them, their content and style labels, and one file read as the models
see it (the body, in centimetres with y up, resampled, optionally cut).

Labels are optional: a ``NAME.json`` beside ``NAME.bvh`` holding ``{"content": i,
"style": j}`` indexes the lines of ``content_label.txt`` and ``style_label.txt`` (looked
for beside the BVH files, in their folder's ``cfg/`` and in its parent's ``cfg/``), as
in the Bandai-Namco data; a clip without labels has content and style None.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Sequence

from .bvh import load_motion
from .kinematics import subtree_motion
from .resample import resample
from .root import RootOptions, hips_index
from .types import Motion

# The contents path-controlled models are trained on unless told otherwise (train --contents).
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right")


def motion_folders(folders: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    """One folder, or several (a sequence, or strings joined with ``os.pathsep`` as in
    ``MOTION_DATA=/data/a:/data/b``, also as a command-line argument), as a list of paths."""
    if isinstance(folders, (str, os.PathLike)):
        folders = [folders]
    result = [Path(part) for folder in folders for part in str(folder).split(os.pathsep) if part]
    if not result:
        raise FileNotFoundError("no motion folder given")
    return result


def find_bvh_files(folders: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    """BVH files in each folder or its ``data/`` subfolder, sorted by name within each
    folder. Several folders pool their clips; their file names must differ, because a
    file's stem names its take."""
    files: list[Path] = []
    for folder in motion_folders(folders):
        files += _bvh_files_in(folder)
    stems: dict[str, Path] = {}
    for path in files:
        if path.stem in stems:
            raise ValueError(f"{path}: a clip named {path.stem!r} is also in {stems[path.stem].parent}; "
                             "clips of pooled folders need different names")
        stems[path.stem] = path
    return files


def _bvh_files_in(folder: Path) -> list[Path]:
    if not folder.is_dir():
        raise FileNotFoundError(f"motion folder {folder} does not exist")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".bvh")
    if not files and (folder / "data").is_dir():
        files = sorted(p for p in (folder / "data").iterdir() if p.suffix.lower() == ".bvh")
    if not files:
        raise FileNotFoundError(f"no .bvh files in {folder} (or {folder / 'data'})")
    return files


def label_name_file(folder: Path, kind: str) -> Path | None:
    """The ``{kind}_label.txt`` that names the labels of the clips in ``folder``: beside
    them, in ``folder/cfg`` or in ``folder/../cfg``."""
    for place in (folder, folder / "cfg", folder.parent / "cfg"):
        path = place / f"{kind}_label.txt"
        if path.is_file():
            return path
    return None


def _label_names(folder: Path, kind: str) -> tuple[Path, list[str]] | None:
    """The ``{kind}_label.txt`` that covers ``folder`` and its labels, or None."""
    path = label_name_file(folder, kind)
    if path is None:
        return None
    try:
        lines = [line.strip() for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not UTF-8 text (byte {error.start})") from None
    # Drop a shared "dataset-1_" style prefix, up to its last underscore.
    prefix = os.path.commonprefix(lines)
    cut = prefix.rfind("_") + 1 if len(lines) > 1 else 0
    return path, [line[cut:] for line in lines]


def read_labels(bvh_path: Path) -> tuple[str | None, str | None]:
    """(content, style) of a clip from its JSON side file, or (None, None). Where a label
    list covers the folder, a label is one of its lines, by index or by name."""
    side = bvh_path.with_suffix(".json")
    if not side.is_file():
        return None, None
    try:
        data = json.loads(side.read_text(encoding="utf-8"))
    except UnicodeDecodeError as error:
        raise ValueError(f"{side}: not UTF-8 text (byte {error.start})") from None
    except json.JSONDecodeError as error:
        raise ValueError(f"{side}:{error.lineno}: invalid JSON ({error.msg})") from None
    except (ValueError, RecursionError) as error:  # a number of thousands of digits, arrays nested thousands deep
        raise ValueError(f"{side}: not a label file ({error})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{side}: expected a JSON object with 'content' and 'style', got a {type(data).__name__}")
    result = []
    for kind in ("content", "style"):
        index = data.get(kind)
        listed = _label_names(bvh_path.parent, kind)
        if index is None:
            result.append(None)
        elif isinstance(index, bool) or not isinstance(index, int | str):
            raise ValueError(f"{side}: {kind!r} must be a label index or name, got {index!r}")
        elif listed is None:  # no label list: the label as given
            result.append(str(index))
        elif isinstance(index, int):
            names_file, names = listed
            if not 0 <= index < len(names):
                raise ValueError(f"{side}: {kind!r} is {index}, but {names_file} lists {len(names)} labels "
                                 f"(0 to {len(names) - 1})")
            result.append(names[index])
        else:
            names_file, names = listed
            if not any(content_matches(index, name) for name in names):
                shown = ", ".join(names[:10]) + (f" and {len(names) - 10} more" if len(names) > 10 else "")
                raise ValueError(f"{side}: {kind!r} is {index!r}, which is not a label of {names_file} ({shown})")
            result.append(index)
    return result[0], result[1]


def content_matches(content: str | None, wanted: str) -> bool:
    """Whether a clip's content label is ``wanted``, also across a dataset prefix:
    ``dataset-2_walk`` matches ``walk`` and the other way round."""
    if content is None:
        return False
    return content == wanted or content.endswith(f"_{wanted}") or wanted.endswith(f"_{content}")


def contents_or_all(folder: str | os.PathLike | Sequence[str | os.PathLike],
                    contents: tuple[str, ...] | None) -> tuple[str, ...] | None:
    """``contents`` where the clips have content labels; None (every clip, as one
    content) for folders without any."""
    if contents is None or any(read_labels(path)[0] is not None for path in find_bvh_files(folder)):
        return contents
    return None


def choose_files(folder: str | os.PathLike | Sequence[str | os.PathLike], contents: tuple[str, ...] | None
                 ) -> tuple[list[Path], dict[Path, tuple[str | None, str | None]]]:
    """The BVH files of ``folder`` (or several, pooled) whose content is one of
    ``contents`` (all where None), and every file's (content, style) labels."""
    files = find_bvh_files(folder)
    labels = {f: read_labels(f) for f in files}
    if contents is not None:
        files = [f for f in files if any(content_matches(labels[f][0], c) for c in contents)]
        if not files:
            folders = ", ".join(str(f) for f in motion_folders(folder))
            raise ValueError(f"no clips in {folders} have content in {list(contents)}")
    return files, labels


def load_body_motion(path: str | os.PathLike, fps: float, seconds: float | None = None,
                     scale: float = 1.0, root: RootOptions = RootOptions(), up: str = "y",
                     start: float = 0.0) -> Motion:
    """A BVH clip as the models see it: in centimetres with y up (from the file's unit
    ``scale`` and ``up`` axis), resampled to ``fps``, reduced to the body (the hips and
    below), and cut (positions only) to the ``seconds`` after ``start`` seconds into the
    take when given (``cut_motion``)."""
    motion = resample(load_motion(path, scale, up), fps)
    motion = subtree_motion(motion, hips_index(motion.skeleton, root.hips))
    return cut_motion(motion, seconds, start, path)


def cut_motion(motion: Motion, seconds: float | None = None, start: float = 0.0,
               source: str | os.PathLike = "the take") -> Motion:
    """The positions of the ``seconds`` after ``start`` seconds into a take (the whole
    take where neither is given). Frames are counted as ``round(seconds * fps)``, as
    controls count them; ``source`` names the take in the error for a start past its end."""
    if seconds is None and not start:
        return motion
    fps = motion.fps
    first = int(round(start * fps))
    if first >= motion.n_frames:
        raise ValueError(f"{source}: the take lasts {motion.n_frames} frames at {fps:g} fps and so ends "
                         f"before {start:g} s into it")
    last = motion.n_frames if seconds is None else first + int(round(seconds * fps))
    return Motion(motion.positions[first:last], motion.fps, motion.skeleton)


__all__ = ["LOCOMOTION", "choose_files", "content_matches", "contents_or_all", "cut_motion", "find_bvh_files", "label_name_file", "load_body_motion", "motion_folders", "read_labels"]
