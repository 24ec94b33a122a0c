"""Build a training set from a folder of BVH files, cache it, and serve windows.

Each clip is read, reduced to the body (the hips and everything below), resampled,
optionally augmented (training clips only), and encoded into both representations.
The result is cached as ``.npz`` under a fingerprint of the input files' contents and
every option, so a changed file or option rebuilds it and nothing else does.

Labels are optional: a ``NAME.json`` beside ``NAME.bvh`` holding ``{"content": i,
"style": j}`` indexes the lines of ``content_label.txt`` and ``style_label.txt`` (looked
for beside the BVH files, in their folder's ``cfg/`` and in its parent's ``cfg/``), as
in the Bandai-Namco data; a clip without labels has content and style None.

Units: every clip is read in centimetres with y up; the files' unit and up axis are
given in the options or detected (``unit_detection``), and the options that the
dataset (and every checkpoint trained on it) keeps record the choice.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
from tqdm import tqdm

from .augment import mirror, reverse, window_count, windows
from ..files import write_atomic
from .bvh import BVHError, load_motion
from .features import AngleFeatureSpec, angle_feature_spec, encode_angles, encode_positions
from .kinematics import subtree_motion
from .resample import resample
from .root import RootOptions, hips_index, limb_root_pairs
from .types import Motion, Skeleton
from .unit_detection import choose_units
from .units import detect_up

FORMAT_VERSION = 1  # bump when the cached arrays change meaning
SPLITS = ("train", "validation", "test")
# The contents path-controlled models are trained on unless told otherwise (train --contents).
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right")
MAX_FPS = 1000.0  # motion capture runs at hundreds of frames per second at most


@dataclass(frozen=True)
class DatasetOptions:
    """Everything that decides the contents of a dataset (all part of its fingerprint)."""

    fps: float = 20.0
    window_seconds: float = 4.0
    overlap: float = 0.5
    mirror: bool = True
    reverse: bool = False
    contents: tuple[str, ...] | None = None  # keep only these content labels
    holdout_fraction: float = 0.1  # of the takes of each content, held out for testing
    # Of each content's remaining takes, held out for choosing checkpoints during training:
    # never trained on, and never reported, so held-out (test) figures stay unbiased.
    validation_fraction: float = 0.1
    seed: int = 0
    angle_representation: str = "quaternion"
    mirror_pairs: dict[str, str] | None = None
    scale: float | None = None  # file units to centimetres; None: detected when building
    root: RootOptions = field(default_factory=RootOptions)
    up: str | None = None  # the files' up axis, "y" or "z"; None: detected when building

    def __post_init__(self) -> None:
        # Checked here, before any file is read or cache written: each value below would
        # otherwise give a dataset that is silently wrong (no test takes, no windows) or
        # an error far from its cause.
        def refuse(name: str, rule: str) -> None:
            raise ValueError(f"dataset option {name} must be {rule}, got {getattr(self, name)!r}")

        if not (math.isfinite(self.fps) and 0 < self.fps <= MAX_FPS):
            refuse("fps", f"a number of frames per second above 0 and at most {MAX_FPS:g}")
        if not (math.isfinite(self.window_seconds) and self.window_seconds > 0) or self.window_frames < 2:
            refuse("window_seconds", f"long enough for two frames at {self.fps:g} fps")
        if not 0 <= self.overlap < 1:
            refuse("overlap", "at least 0 and below 1")
        for name in ("holdout_fraction", "validation_fraction"):
            if not 0 <= getattr(self, name) < 1:
                refuse(name, "at least 0 and below 1")
        if self.scale is not None and not (math.isfinite(self.scale) and self.scale > 0):
            refuse("scale", "a positive number (file units to centimetres)")

    @property
    def window_frames(self) -> int:
        return int(round(self.window_seconds * self.fps))

    @property
    def hop_frames(self) -> int:
        return max(1, int(round(self.window_frames * (1.0 - self.overlap))))

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "DatasetOptions":
        data = dict(data)
        data["root"] = RootOptions(**data["root"])
        data.setdefault("up", "y")  # recorded before the up axis was an option: y
        if data.get("contents") is not None:
            data["contents"] = tuple(data["contents"])
        return cls(**data)


@dataclass(frozen=True)
class Clip:
    """One (possibly augmented) clip of the dataset; its frames are rows start:stop."""

    name: str  # the BVH file's stem
    take: str  # what the train/test split keeps together
    content: str | None
    style: str | None
    augmentation: str  # "", "mirror", "reverse" or "mirror+reverse"
    split: str
    start: int
    stop: int
    has_angles: bool


@dataclass(frozen=True)
class Standardizer:
    """Per-dimension mean and standard deviation; constant dimensions get std 1."""

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, data: np.ndarray) -> "Standardizer":
        flat = data.reshape(-1, data.shape[-1])
        std = flat.std(axis=0)
        return cls(flat.mean(axis=0), np.where(std < 1e-6, 1.0, std))

    def apply(self, data: np.ndarray) -> np.ndarray:
        return (data - self.mean) / self.std

    def invert(self, data: np.ndarray) -> np.ndarray:
        return data * self.std + self.mean

    def to_dict(self) -> dict:
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_dict(cls, data: dict) -> "Standardizer":
        return cls(np.asarray(data["mean"]), np.asarray(data["std"]))


@dataclass
class MotionDataset:
    """Encoded clips, their labels and split, and the standardisation statistics.

    ``arrays`` holds per-frame rows of every clip, concatenated: ``pose`` (3 × joints),
    ``control`` (forward, sideways, yaw velocity) and ``angles`` (NaN for clips without
    joint rotations, i.e. mirrored ones). ``stats`` are fitted on the training clips
    and travel with the dataset into every checkpoint trained on it.
    """

    options: DatasetOptions
    skeleton: Skeleton  # the body skeleton (hips as root)
    angle_spec: AngleFeatureSpec
    clips: list[Clip]
    arrays: dict[str, np.ndarray]
    stats: dict[str, Standardizer]
    fingerprint: str

    def clip_arrays(self, clip: Clip) -> dict[str, np.ndarray]:
        return {key: value[clip.start : clip.stop] for key, value in self.arrays.items()}

    def select(self, split: str, augmented: bool = True) -> list[Clip]:
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; use one of {SPLITS}")
        return [c for c in self.clips if c.split == split and (augmented or not c.augmentation)]

    def windows(self, split: str, keys: tuple[str, ...] = ("pose", "control"), standardize: bool = True) -> dict[str, np.ndarray]:
        """Fixed-length overlapping windows (n, frames, dims) of the chosen arrays.

        Clips lacking a requested array (angles of mirrored clips) are left out.
        """
        clips = [c for c in self.select(split) if c.has_angles or "angles" not in keys]
        out = {}
        for key in keys:
            parts = [
                windows(self.arrays[key][c.start : c.stop], self.options.window_frames, self.options.hop_frames)
                for c in clips
            ]
            data = np.concatenate(parts) if parts else np.empty((0, self.options.window_frames, self.arrays[key].shape[1]))
            out[key] = (self.stats[key].apply(data) if standardize else data).astype(np.float32)
        return out

    def labels(self, split: str, kind: str = "content") -> list[str | None]:
        """The content or style label of each window returned by ``windows(split)``."""
        result = []
        for clip in self.select(split):
            n = window_count(clip.stop - clip.start, self.options.window_frames, self.options.hop_frames)
            result += [getattr(clip, kind)] * n
        return result

    def training_windows(self) -> int:
        """How many windows the training clips give (augmented clips included)."""
        return sum(window_count(c.stop - c.start, self.options.window_frames, self.options.hop_frames)
                   for c in self.select("train"))

    def require_training_windows(self) -> int:
        """How many training windows there are; ValueError when there are none (every
        training take shorter than one window), rather than a model trained on nothing."""
        train = self.select("train")
        count = self.training_windows()
        if count == 0:
            longest = max((c.stop - c.start for c in train), default=0)
            raise ValueError(
                f"no training windows: {len(train)} training clip(s), the longest {longest} frame(s) at "
                f"{self.options.fps:g} fps, and a window needs {self.options.window_frames} "
                f"({self.options.window_seconds:g} s); use longer takes or a shorter window")
        return count

    def takes_without_windows(self, split: str) -> list[str]:
        """The takes of a split too short for one window: they give the models nothing."""
        return [c.name for c in self.select(split, augmented=False)
                if window_count(c.stop - c.start, self.options.window_frames, self.options.hop_frames) == 0]

    def window_warnings(self) -> list[str]:
        """What the user should know about takes that give no windows, one line each."""
        lines = []
        seconds = f"{self.options.window_seconds:g}-s"
        for split, role in (("train", "training"), ("validation", "validation"), ("test", "held-out")):
            short = self.takes_without_windows(split)
            if short:
                names = ", ".join(short[:10]) + (f" and {len(short) - 10} more" if len(short) > 10 else "")
                lines.append(f"{len(short)} {role} take(s) shorter than one {seconds} window give no windows: {names}")
        return lines

    def save(self, path: str | os.PathLike) -> Path:
        """Write the dataset as one ``.npz`` (no pickles), atomically."""
        meta = {
            "format_version": FORMAT_VERSION,
            "options": self.options.to_dict(),
            "skeleton": self.skeleton.to_dict(),
            "angle_spec": self.angle_spec.to_dict(),
            "clips": [dataclasses.asdict(c) for c in self.clips],
            "stats": {k: s.to_dict() for k, s in self.stats.items()},
            "fingerprint": self.fingerprint,
        }
        buffer = io.BytesIO()
        np.savez_compressed(buffer, meta=np.array(json.dumps(meta)), **self.arrays)
        path = Path(path)
        write_atomic(path, buffer.getvalue())
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> "MotionDataset":
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta.get("format_version") != FORMAT_VERSION:
                raise ValueError(f"{path}: dataset cache format {meta.get('format_version')} is not {FORMAT_VERSION}; rebuild it")
            arrays = {k: data[k] for k in data.files if k != "meta"}
        return cls(
            options=DatasetOptions.from_dict(meta["options"]),
            skeleton=Skeleton.from_dict(meta["skeleton"]),
            angle_spec=AngleFeatureSpec.from_dict(meta["angle_spec"]),
            clips=[Clip(**c) for c in meta["clips"]],
            arrays=arrays,
            stats={k: Standardizer.from_dict(s) for k, s in meta["stats"].items()},
            fingerprint=meta["fingerprint"],
        )


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


def take_of(stem: str) -> str:
    """The take a file belongs to: its name without augmentation; one file is one take."""
    return stem


def split_takes(takes: list[tuple[str, str | None]], fraction: float, seed: int) -> set[str]:
    """The held-out takes: for each content, a seeded-random ``fraction`` (at least one
    when the content has two or more takes)."""
    by_content: dict[str | None, list[str]] = {}
    for take, content in takes:
        by_content.setdefault(content, []).append(take)
    held = set()
    for content, group in sorted(by_content.items(), key=lambda kv: str(kv[0])):
        group = sorted(set(group), key=lambda t: hashlib.sha256(f"{seed}:{t}".encode()).hexdigest())
        n = int(round(fraction * len(group)))
        if fraction > 0 and len(group) >= 2:
            n = max(1, min(n, len(group) - 1))
        held.update(group[:n])
    return held


def fingerprint(files: list[Path], options: DatasetOptions) -> str:
    """A hash of the input files' names and contents, the options and the format."""
    settings = options.to_dict()
    # Options added after datasets were first fingerprinted are left out at the value
    # they had before they existed, so that existing datasets keep their fingerprints.
    if settings["up"] == "y":
        del settings["up"]
    if settings["root"]["pairs"] is None:
        del settings["root"]["pairs"]
    digest = hashlib.sha256()
    digest.update(json.dumps([FORMAT_VERSION, settings], sort_keys=True).encode())
    for path in files:
        digest.update(path.name.encode())
        digest.update(hashlib.sha256(path.read_bytes()).digest())
        side = path.with_suffix(".json")
        if side.is_file():
            digest.update(side.read_bytes())
    return digest.hexdigest()


def cache_key(data_fingerprint: str, files: list[Path]) -> str:
    """The name of a dataset's cache: its fingerprint and the label-name files its clips'
    labels were read through (a renamed label rebuilds the cache; the data are the same,
    so the fingerprint that checkpoints record does not change)."""
    digest = hashlib.sha256(data_fingerprint.encode())
    for folder in dict.fromkeys(path.parent for path in files):
        for kind in ("content", "style"):
            names = label_name_file(folder, kind)
            if names is not None:
                digest.update(f"{kind}:{names.name}".encode())
                digest.update(hashlib.sha256(names.read_bytes()).digest())
    return digest.hexdigest()


def default_cache_dir() -> Path:
    return Path(os.environ.get("MOTION_CACHE_DIR", Path(os.environ.get("STUDYAPP_VAR_DIR", "var")) / "cache"))


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


def with_units(files: list[Path], options: DatasetOptions, progress: bool = False) -> DatasetOptions:
    """``options`` with the unit and up axis it leaves open (None) detected from
    ``files``; the choice is printed when ``progress`` is on."""
    choice = choose_units(files, options.scale, options.up, options.root)  # reads no file where both are given
    if progress:
        print(choice.description)
    return dataclasses.replace(options, scale=choice.units.scale, up=choice.units.up)


def take_splits(files: list[Path], labels: dict[Path, tuple[str | None, str | None]],
                options: DatasetOptions) -> dict[str, str]:
    """The split ("train", "validation" or "test") of each file's take: a seeded
    fraction of each content's takes held out for testing, then of the others for
    validation (``split_takes``)."""
    takes = [(take_of(f.stem), labels[f][0]) for f in files]
    held_out = split_takes(takes, options.holdout_fraction, options.seed)
    validation = split_takes([t for t in takes if t[0] not in held_out], options.validation_fraction, options.seed + 1)
    return {take: "test" if take in held_out else "validation" if take in validation else "train" for take, _ in takes}


def build_dataset(
    folder: str | os.PathLike | Sequence[str | os.PathLike],
    options: DatasetOptions = DatasetOptions(),
    cache_dir: str | os.PathLike | None = None,
    progress: bool = True,
) -> MotionDataset:
    """Read, encode and split every BVH clip in ``folder`` (or several folders, pooled);
    reuse the cache when valid. Units the options leave open (None) are detected, and
    the choice is printed when ``progress`` is on."""
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    if cache.exists() and not cache.is_dir():
        raise ValueError(f"the cache folder {cache} is a file; name a folder (or none, for {default_cache_dir()})")
    files, labels = choose_files(folder, options.contents)
    detect_up_axis = options.up is None
    options = with_units(files, options, progress)
    key = fingerprint(files, options)
    cached = cache / f"dataset-{cache_key(key, files)[:20]}.npz"
    if cached.is_file():
        return MotionDataset.load(cached)

    splits = take_splits(files, labels, options)
    skeleton = spec = None
    clips, parts = [], {"pose": [], "control": [], "angles": []}
    rows, other_up = 0, []
    for path in tqdm(files, desc="encoding clips", unit="clip", disable=not progress):
        with _naming(path):
            body = load_body_motion(path, options.fps, scale=options.scale, root=options.root, up=options.up)
            if skeleton is None:
                skeleton = body.skeleton
                limb_root_pairs(skeleton, options.root.pairs)  # refuses a rig with no facing (_naming names the file)
                spec = angle_feature_spec(skeleton, options.angle_representation, pairs=options.root.pairs)
            elif body.skeleton.names != skeleton.names:
                raise ValueError(f"{path}: its skeleton differs from the first file's; one dataset needs one skeleton")
            if detect_up_axis and detect_up(body) != "y":
                other_up.append(path.name)
            split = splits[take_of(path.stem)]
            for augmentation, motion in _augmented(body, options, split == "train"):
                encoded = encode_positions(motion, options.root)
                angles = encode_angles(motion, spec).values if motion.rotations is not None else np.full((motion.n_frames, spec.size), np.nan)
                for name, value in (("pose", encoded.pose), ("control", encoded.control), ("angles", angles)):
                    parts[name].append(value.astype(np.float32))
                content, style = labels[path]
                clips.append(Clip(path.stem, take_of(path.stem), content, style, augmentation, split,
                                  rows, rows + motion.n_frames, motion.rotations is not None))
                rows += motion.n_frames
    if other_up:
        more = f" and {len(other_up) - 10} more" if len(other_up) > 10 else ""
        raise ValueError(f"the files mix up axes: {files[0].name} stands along {options.up}, but not "
                         f"{', '.join(other_up[:10])}{more}; give the up axis (--up)")
    arrays = {k: np.concatenate(v) for k, v in parts.items()}
    train = [c for c in clips if c.split == "train"]
    stats = {
        key: Standardizer.fit(np.concatenate([arrays[key][c.start : c.stop] for c in train if key != "angles" or c.has_angles]))
        for key in arrays
    }
    dataset = MotionDataset(options, skeleton, spec, clips, arrays, stats, key)
    if dataset.training_windows():  # else no model can learn from it: the command refusing it leaves no cache behind
        dataset.save(cached)
    return dataset


@contextmanager
def _naming(path: Path) -> Iterator[None]:
    """A clip that cannot be used names itself: the checks deep in the motion code (a rig
    without left/right pairs, values that overflow) know nothing of files."""
    try:
        yield
    except ValueError as error:
        if isinstance(error, BVHError) or str(error).startswith(str(path)):
            raise  # names its file (and line) already
        raise ValueError(f"{path}: {error}") from error


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


def _augmented(motion: Motion, options: DatasetOptions, train: bool):
    """The clip and, for training clips, its augmented copies."""
    yield "", motion
    if not train:
        return
    if options.mirror:
        yield "mirror", mirror(motion, options.mirror_pairs)
    if options.reverse:
        yield "reverse", reverse(motion)
        if options.mirror:
            yield "mirror+reverse", reverse(mirror(motion, options.mirror_pairs))
