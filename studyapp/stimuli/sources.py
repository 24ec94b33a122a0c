"""Where a system's motion comes from: one interface for every kind of system.

Every system answers the same question, "the motion for this control", through its
source: a checkpoint (a built-in model kind or one an installed plugin registers) is
sampled, the natural system (NAT) reads the held-out clip the control came from, and
submitted motion (another lab's files, one per control) is read from where it was
stored. The stimuli module asks a system's source for a clip and renders every answer
the same way. Uploaded videos are the one source that is never rendered: their
stimuli are made finished when they are uploaded, so the source plans no clips.

``source_of(system)`` picks the source by ``System.source_kind``; a new kind of system
is one more class here and one more entry in ``SOURCES``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Protocol

import numpy as np
from django.conf import settings

from generation.control import PathControl, in_control_frame
from generation.motion.npz import load_motion_npz, save_motion_npz
from generation.motion.root import RootOptions, root_trajectory
from generation.motion.types import Motion
from studyapp.models import ControlSignal, Stimulus, StoredDataError, Study, System, json_object
from studyapp.stimuli.controls import natural_options, study_options
from studyapp.stimuli.natural import natural_motion
from studyapp.stimuli.submissions import read_stored_motion

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Clip:
    """A source's answer: the motion, and the floor path (frames × 2, x and z) drawn under it."""

    motion: Motion
    floor: np.ndarray
    starts_on_path: bool = True  # starts where every control's path does (natural motion: where its take was)

    def on_control_path(self, frames: int, root: RootOptions) -> Motion:
        """The motion moved to start where every control's path starts, facing as it
        does, and at most ``frames`` long: ready to be set against a control's path."""
        motion = self.motion if self.starts_on_path else in_control_frame(self.motion, root)
        frames = min(frames, motion.n_frames)
        return Motion(motion.positions[:frames], motion.fps, motion.skeleton)


class MotionSource(Protocol):
    """What every kind of system answers."""

    samples: bool  # whether its motion is sampled from a model (on STUDY_SAMPLE_QUEUE's workers)

    def controls(self, system: System, controls: list[ControlSignal]) -> list[ControlSignal]:
        """The controls of the study this system has motion for."""

    def identity(self, system: System, control: ControlSignal, seed: int) -> dict:
        """What the motion depends on besides the control: ``source``, ``seed`` and ``temperature``
        (None where they do not matter). Part of the stimulus's content key."""

    def clip(self, stimulus: Stimulus) -> Clip:
        """The motion of ``stimulus.system`` for ``stimulus.control``."""


def commanded_floor(control: ControlSignal, motion: Motion) -> np.ndarray:
    """The floor path drawn under a generated clip: the path it was told to follow, or,
    for label controls, where its root went."""
    signal = control.signal()
    if isinstance(signal, PathControl):
        return signal.path().xz
    return root_trajectory(motion, study_options(control.study).root).xz


def sampling_device(setting: str) -> str:
    """The torch device STUDY_DEVICE names: "auto" is CUDA where a GPU is present."""
    if setting != "auto":
        return setting
    import torch  # workers only

    return "cuda" if torch.cuda.is_available() else "cpu"


@lru_cache(maxsize=4)
def _generator(path: str, digest: str, device: str):
    """A worker keeps a few models loaded; the digest keys the cache to the file's content."""
    from generation.generator import Generator  # torch loads in workers, not in every web process

    generator = Generator.load(path, device)
    logger.info("%s samples in %s (precision auto)", path, generator.resolve_precision())
    return generator


def sampled_folder() -> Path:
    """Where sampled motion lies, one ``<content key>.npz`` per clip; studies whose clips
    have the same content key share the file (``removal`` deletes what none refers to).
    Only what this server's workers sampled is kept here."""
    return Path(settings.VAR_DIR) / "sampled"


def imported_sampled_folder(study: Study) -> Path:
    """Where the motion a study's bundle carried is kept: under that study (by its key,
    which no later study gets), never in the shared folder, where a clip of any study with
    the same content key would be drawn from it instead of being sampled."""
    return sampled_folder() / "imported" / study.key


def imported_sampled_path(stimulus: Stimulus) -> Path:
    """Where the motion the bundle of a stimulus's study carried for it is kept."""
    return imported_sampled_folder(stimulus.study) / f"{stimulus.content_key}.npz"


def sampled_path(stimulus: Stimulus) -> Path:
    """Where a stimulus's motion is: the motion its study's bundle carried, where it came
    with one, else where a sampling worker leaves it for the rendering worker (named by its
    content key, so it is the motion of exactly this clip)."""
    imported = imported_sampled_path(stimulus)
    return imported if imported.is_file() else sampled_folder() / f"{stimulus.content_key}.npz"


class CheckpointSource:
    """A model checkpoint of any registered kind, sampled with the stimulus's seed.

    With ``sample_ahead``, a worker on STUDY_SAMPLE_QUEUE samples every control of one
    system in one task, the model loaded once and the controls sampled together,
    STUDY_SAMPLE_BATCH at a time (``Generator.sample_batch``: each clip from its own seed,
    so a clip is the same whichever batch it was sampled in), and leaves the motion at
    ``sampled_path``; the rendering worker reads it. Where nothing was sampled ahead,
    ``clip`` samples the one clip and leaves it there too.
    """

    samples = True  # dispatch sends its stimuli to the sampling queue first

    def controls(self, system: System, controls: list[ControlSignal]) -> list[ControlSignal]:
        return controls

    def identity(self, system: System, control: ControlSignal, seed: int) -> dict:
        return {"source": f"checkpoint:{system.checkpoint_digest}", "seed": seed, "temperature": system.temperature}

    def sample_ahead(self, system: System, stimuli: list[Stimulus]) -> dict[int, Exception]:
        """Sample the motion of ``system``'s ``stimuli`` not sampled yet into ``sampled_path``;
        what went wrong, by stimulus id. A control the model cannot follow fails alone; a
        failing batch fails its stimuli (the error names the reason) and the next batch
        is sampled all the same."""
        todo = [stimulus for stimulus in stimuli if not sampled_path(stimulus).is_file()]
        if not todo:
            return {}
        try:
            generator = self._loaded(system)
        except Exception as error:  # a missing or unreadable checkpoint: nothing of the system samples
            return {stimulus.pk: error for stimulus in todo}
        failed: dict[int, Exception] = {}
        checked = []
        for stimulus in todo:
            try:
                signal = stimulus.control.signal()
                generator.check_control(signal)
            except ValueError as error:
                failed[stimulus.pk] = error
            else:
                checked.append((stimulus, signal))
        size = settings.STUDY_SAMPLE_BATCH
        for batch in (checked[i:i + size] for i in range(0, len(checked), size)):
            try:
                motions = generator.sample_batch([signal for _, signal in batch], [s.seed for s, _ in batch],
                                                 temperature=system.temperature)
            except Exception as error:  # e.g. out of memory: these clips fail, the next batch may not
                failed.update((stimulus.pk, error) for stimulus, _ in batch)
                continue
            for (stimulus, _), motion in zip(batch, motions):
                save_motion_npz(motion, sampled_path(stimulus))
        return failed

    def clip(self, stimulus: Stimulus) -> Clip:
        sampled = sampled_path(stimulus)
        if sampled.is_file():
            motion = load_motion_npz(sampled)
        else:
            signal = stimulus.control.signal()
            motion = self._loaded(stimulus.system).sample(signal, n=1, seed=stimulus.seed,
                                                          temperature=stimulus.system.temperature)[0]
            save_motion_npz(motion, sampled)  # the study's motion, for export_motion
        return Clip(motion, commanded_floor(stimulus.control, motion))

    @staticmethod
    def _loaded(system: System):
        path = system.checkpoint_path()
        if path is None or not path.is_file():
            raise FileNotFoundError(f"the checkpoint of {system.name} is missing ({path})")
        return _generator(str(path), system.checkpoint_digest, sampling_device(settings.STUDY_DEVICE))


class NaturalClips:
    """NAT: the held-out clip each held-out control came from, as the models see the data."""

    samples = False

    def controls(self, system: System, controls: list[ControlSignal]) -> list[ControlSignal]:
        return [c for c in controls if c.origin == ControlSignal.Origin.HELD_OUT and c.source_clip]

    def identity(self, system: System, control: ControlSignal, seed: int) -> dict:
        return {"source": f"natural:{control.source_clip}", "seed": None, "temperature": None}

    def clip(self, stimulus: Stimulus) -> Clip:
        control = stimulus.control
        options = natural_options(control)
        motion = natural_motion(control, options)
        return Clip(motion, root_trajectory(motion, options.root).xz, starts_on_path=False)


class SubmittedMotion:
    """Motion another lab made for the study's exported controls, validated and stored as
    one ``.npz`` per control (``studyapp.stimuli.submissions``)."""

    samples = False

    def controls(self, system: System, controls: list[ControlSignal]) -> list[ControlSignal]:
        stored = set(json_object(system, "metadata").get("controls") or [])
        return [c for c in controls if c.name in stored]

    def identity(self, system: System, control: ControlSignal, seed: int) -> dict:
        return {"source": f"submitted:{system.checkpoint_digest}:{control.name}", "seed": None, "temperature": None}

    def clip(self, stimulus: Stimulus) -> Clip:
        if not isinstance(json_object(stimulus.system, "metadata").get("folder"), str):
            raise StoredDataError(stimulus.system, "metadata", "names no folder of submitted motion")
        motion = read_stored_motion(stimulus.system, stimulus.control)
        return Clip(motion, commanded_floor(stimulus.control, motion))


class UploadedVideos:
    """Videos uploaded as they are: finished stimuli from the start, never rendered."""

    samples = False

    def controls(self, system: System, controls: list[ControlSignal]) -> list[ControlSignal]:
        return []

    def identity(self, system: System, control: ControlSignal, seed: int) -> dict:
        raise ValueError("an uploaded video has no motion to plan")

    def clip(self, stimulus: Stimulus) -> Clip:
        raise ValueError("an uploaded video has nothing to generate")


SOURCES: dict[str, MotionSource] = {
    System.SourceKind.CHECKPOINT: CheckpointSource(),
    System.SourceKind.NATURAL: NaturalClips(),
    System.SourceKind.SUBMITTED: SubmittedMotion(),
    System.SourceKind.VIDEO: UploadedVideos(),
}


def source_of(system: System) -> MotionSource:
    """The source of a system's motion (StoredDataError, a ValueError, for a system that has none)."""
    source = SOURCES.get(system.source_kind)
    if source is None:
        raise StoredDataError(system, "kind", f"{system.kind!r} names no source of motion, and it has no checkpoint "
                                              f"(sources: {', '.join(SOURCES)})")
    return source


__all__ = ["Clip", "MotionSource", "SOURCES", "commanded_floor", "imported_sampled_folder", "imported_sampled_path",
           "sampled_folder", "sampled_path", "source_of"]
