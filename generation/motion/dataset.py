"""Build a training set from a folder of BVH files, cache it, and serve windows.

Each clip is read (``clip_files``), reduced to the body (the hips and everything below),
resampled, split by take (``splits``), optionally augmented (training clips only), and
encoded into both representations. The result is cached as ``.npz`` under a fingerprint
of the input files' contents and every option (``dataset_options``), so a changed file
or option rebuilds it and nothing else does.

Units: every clip is read in centimetres with y up; the files' unit and up axis are
given in the options or detected (``unit_detection``), and the options that the
dataset (and every checkpoint trained on it) keeps record the choice.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from tqdm import tqdm

from ..files import write_atomic
from .augment import mirror, reverse, window_count, windows
from .bvh import BVHError
from .clip_files import choose_files, label_name_file, load_body_motion
from .dataset_options import DatasetOptions, with_units
from .features import AngleFeatureSpec, angle_feature_spec, encode_angles, encode_positions
from .root import limb_root_pairs
from .splits import SPLITS, take_of, take_splits
from .types import Motion, Skeleton
from .skeleton_units import detect_up

FORMAT_VERSION = 1  # bump when the cached arrays change meaning


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


__all__ = ["Clip", "MotionDataset", "Standardizer", "build_dataset", "cache_key", "default_cache_dir", "fingerprint"]
