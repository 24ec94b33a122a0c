"""The motion capture behind held-out controls and NAT clips: ``settings.MOTION_DATA``
(one folder of BVH files or several joined with ``:``, pooled as ``train`` pools them),
or the folders a researcher names when adding held-out controls.

A held-out control names its take by the path inside the folder that holds it
(``data/dataset-2_walk_active_001.bvh``), so a study made on one folder still finds its
clips when more folders are added beside it: take names differ across pooled folders.
It also records where its take was found and the dataset options it is read with
(``natural_source``): a study without checkpoints reads its takes in the unit and up
axis detected (or given) when the controls were added, and a take of a folder outside
``MOTION_DATA`` is found where it was.
"""

from __future__ import annotations

from pathlib import Path, PurePath

from django.conf import settings

from generation.motion.clip_files import load_body_motion, motion_folders
from generation.motion.dataset_options import DatasetOptions
from generation.motion.types import Motion
from studyapp.models import ControlSignal


def data_folders() -> list[Path]:
    """The folders of ``MOTION_DATA``."""
    return motion_folders(settings.MOTION_DATA)


def source_name(path: Path, folders: list[Path]) -> str:
    """``path`` relative to whichever of ``folders`` holds it."""
    for folder in folders:
        if path.is_relative_to(folder):
            return str(path.relative_to(folder))
    raise ValueError(f"{path} is in none of the motion folders {', '.join(map(str, folders))}")


def natural_source(folders: list[Path], options: DatasetOptions) -> dict:
    """What a held-out control records of its take's source (``ControlSignal.natural``)."""
    return {"folders": [str(folder.absolute()) for folder in folders], "options": options.to_dict()}


def is_take_name(source: str) -> bool:
    """Whether ``source`` names a file inside a motion folder: a relative path that never
    goes up (``..``), so it names nothing outside whichever folder it is looked for in."""
    path = PurePath(source)
    return bool(source) and not path.is_absolute() and ".." not in path.parts


def natural_clip(source: str, recorded: list[str] = ()) -> Path:
    """The BVH file a held-out control was cut from: in the folders it was found in
    (``recorded``), else in those of ``MOTION_DATA``; never outside them."""
    folders = list(dict.fromkeys([*map(Path, recorded), *data_folders()]))
    for folder in folders:
        if is_take_name(source) and (folder / source).is_file():
            return folder / source
    raise FileNotFoundError(f"the natural clip {source} is in none of the motion folders "
                            f"{', '.join(map(str, folders))} (MOTION_DATA)")


def natural_motion(control: ControlSignal, options: DatasetOptions) -> Motion:
    """The frames of its held-out take that a held-out control was cut from, read with
    ``options`` as the models' training data was: the take's first ``control.seconds``,
    or the seconds after the control's lead-in where it has one."""
    path = natural_clip(control.source_clip, control.natural.get("folders", ()))
    return load_body_motion(path, options.fps, control.seconds, options.scale, options.root, options.up,
                            start=control.lead_in_seconds)
