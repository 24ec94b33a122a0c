"""Control signals: what a model is asked to do.

Two kinds, as DESIGN.md says: a *path* (per-frame forward, sideways and yaw velocity in
the root frame, as MoGlow uses) and *attributes* (action and style labels, as HVRNN
uses). Paths come from held-out natural clips or are synthesised from a small JSON or
YAML description: straight lines at a speed, curves, sidestepping, walking backwards,
standing still and speed ramps, as in MoGlow's synthetic control.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from scipy.ndimage import gaussian_filter1d

from .motion.root import RootOptions, RootTrajectory, integrate, root_trajectory, to_root_frame
from .motion.types import Motion

# Seconds of Gaussian smoothing between segments, so speeds change as a person's do.
TRANSITION_SIGMA = 0.25
# Bounds on a synthetic description's numbers: a stimulus lasts seconds, not days, and
# no person walks at 20 m/s or turns ten times a second. Beyond them a description is
# a mistake (or an attack on memory), refused before anything is allocated.
MAX_PATH_SECONDS = 600.0
MAX_SPEED_CM_S = 2000.0
MAX_TURN_RATE_DEG_S = 3600.0


def _number(spec: dict, key: str, default: float, bound: float) -> float:
    """``spec[key]`` as a finite float within ``[-bound, bound]``; the message names the field.
    Only a number is one: text such as "1_0" or "+3" (which float() would read) is refused."""
    raw = spec.get(key, default)
    if isinstance(raw, bool) or not isinstance(raw, int | float):
        raise ValueError(f"{key!r} must be a number, got {repr(raw)[:40]}")
    if abs(raw) > bound or not math.isfinite(raw):  # bound first: float() of a huge int overflows
        raise ValueError(f"{key!r} must be a finite number within ±{bound:g}, got {repr(raw)[:40]}")
    return float(raw)


@dataclass(frozen=True)
class PathControl:
    """(frames, 3) forward (cm/s), sideways (cm/s, left positive) and yaw (rad/s) velocity."""

    velocities: np.ndarray
    fps: float
    name: str = ""
    # The control just before the clip, where there is one (a held-out take's first
    # second): sampling warms up on it instead of holding the first frame.
    lead_in: np.ndarray | None = None

    def __post_init__(self) -> None:
        v = np.asarray(self.velocities, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 2:
            raise ValueError(f"path control needs shape (frames >= 2, 3), got {v.shape}")
        if not np.isfinite(v).all():
            raise ValueError("path control contains NaN or infinity")
        _check_length(len(v), self.fps)
        object.__setattr__(self, "velocities", v)
        if self.lead_in is not None:
            lead = np.asarray(self.lead_in, dtype=np.float64)
            if lead.ndim != 2 or lead.shape[1] != 3 or len(lead) < 1 or not np.isfinite(lead).all():
                raise ValueError(f"a path control's lead-in needs finite values of shape (frames >= 1, 3), got {lead.shape}")
            _check_length(len(lead), self.fps)
            object.__setattr__(self, "lead_in", lead)

    @property
    def n_frames(self) -> int:
        return len(self.velocities)

    def path(self) -> RootTrajectory:
        """The floor path this control traces from the origin, facing +z."""
        return integrate(self.velocities, self.fps)

    def to_dict(self) -> dict:
        data = {"type": "path", "name": self.name, "fps": self.fps, "velocities": self.velocities.round(4).tolist()}
        if self.lead_in is not None:
            data["lead_in"] = self.lead_in.round(4).tolist()
        return data

    def warmup(self, frames: int) -> np.ndarray:
        """The ``frames`` of control that sampling runs on before the clip: the end of the
        lead-in where there is one (its first frame held before it if it is shorter),
        else the clip's first frame held."""
        source = self.velocities[:1] if self.lead_in is None else self.lead_in
        lead = source[-frames:] if frames > 0 else source[:0]
        return np.concatenate([np.repeat(source[:1], frames - len(lead), axis=0), lead])


@dataclass(frozen=True)
class AttributeControl:
    """Action and style labels for a sequence of ``frames`` frames."""

    action: str
    style: str
    frames: int
    fps: float
    name: str = ""

    def __post_init__(self) -> None:
        if not self.action or not self.style:
            raise ValueError("attribute control needs an action and a style label")
        if self.frames < 1:
            raise ValueError(f"attribute control needs frames >= 1, got {self.frames}")
        _check_length(self.frames, self.fps)

    @property
    def n_frames(self) -> int:
        return self.frames

    def to_dict(self) -> dict:
        return {"type": "attributes", "name": self.name, "action": self.action, "style": self.style,
                "frames": self.frames, "fps": self.fps}


Control = PathControl | AttributeControl


def _check_length(frames: int, fps: float) -> None:
    """A control lasts at most MAX_PATH_SECONDS at a positive, finite frame rate: a model
    asked for more would allocate its whole output first."""
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"a control needs a positive, finite fps, got {fps}")
    if frames / fps > MAX_PATH_SECONDS:
        raise ValueError(f"a control of {frames} frames at {fps:g} fps lasts {frames / fps:g} s; "
                         f"at most {MAX_PATH_SECONDS:g} s")


def _frames_of(seconds: float | None, fps: float) -> int | None:
    """``seconds`` as a number of frames (None stays None), refusing what no control can last."""
    if seconds is None:
        return None
    if not (math.isfinite(seconds) and 0 < seconds <= MAX_PATH_SECONDS):
        raise ValueError(f"seconds must be above 0 and at most {MAX_PATH_SECONDS:g}, got {seconds}")
    return int(round(seconds * fps))


def control_from_dict(data: dict) -> Control:
    """Inverse of ``to_dict`` for either kind."""
    if data.get("type") == "path":
        lead_in = data.get("lead_in")
        return PathControl(np.asarray(data["velocities"]), data["fps"], data.get("name", ""),
                           None if lead_in is None else np.asarray(lead_in))
    if data.get("type") == "attributes":
        return AttributeControl(data["action"], data["style"], int(data["frames"]), data["fps"], data.get("name", ""))
    raise ValueError(f"unknown control type {data.get('type')!r}; expected 'path' or 'attributes'")


# Segment types of a synthetic path and what each reads from its description.
def _segment(kind: str, spec: dict, n: int) -> np.ndarray:
    speed = _number(spec, "speed", 120.0, MAX_SPEED_CM_S)
    v = np.zeros((n, 3))
    if kind == "straight":
        v[:, 0] = speed
    elif kind == "curve":
        v[:, 0] = speed
        v[:, 2] = math.radians(_number(spec, "turn_rate", 30.0, MAX_TURN_RATE_DEG_S))  # deg/s, left positive
    elif kind == "sidestep":
        direction = spec.get("direction", "left")
        if direction not in ("left", "right"):
            raise ValueError(f"sidestep direction must be 'left' or 'right', got {direction!r}")
        v[:, 1] = speed if direction == "left" else -speed
    elif kind == "backward":
        v[:, 0] = -speed
    elif kind == "stand":
        pass
    elif kind == "ramp":
        v[:, 0] = np.linspace(_number(spec, "from", 0.0, MAX_SPEED_CM_S), _number(spec, "to", 250.0, MAX_SPEED_CM_S), n)
    else:
        raise ValueError(f"unknown segment type {kind!r}; use straight, curve, sidestep, backward, stand or ramp")
    return v


def synthetic_path(description: dict, fps: float = 20.0) -> PathControl:
    """A path from ``{"name": ..., "segments": [{"type": "straight", "seconds": 3, "speed": 120}, ...]}``.

    Speeds are cm/s, ``turn_rate`` deg/s (left positive); segments join smoothly.
    """
    if not isinstance(description, dict):
        raise ValueError(f"a synthetic path is an object with 'segments', got {type(description).__name__}")
    segments = description.get("segments")
    if not segments or not isinstance(segments, list):
        raise ValueError("a synthetic path needs a non-empty 'segments' list")
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"a synthetic path needs a positive, finite fps, got {fps}")
    parts, total_seconds = [], 0.0
    for i, spec in enumerate(segments):
        if not isinstance(spec, dict):
            raise ValueError(f"segment {i} must be an object, got {spec!r}")
        try:
            seconds = _number(spec, "seconds", 0.0, MAX_PATH_SECONDS)
            if seconds <= 0:
                raise ValueError(f"needs a positive 'seconds', got {spec.get('seconds')!r}")
            total_seconds += seconds
            if total_seconds > MAX_PATH_SECONDS:
                raise ValueError(f"the path's segments last over {MAX_PATH_SECONDS:g} s in all")
            parts.append(_segment(spec.get("type", ""), spec, max(1, int(round(seconds * fps)))))
        except ValueError as error:
            raise ValueError(f"segment {i}: {error}") from None
    velocities = np.concatenate(parts)
    if len(parts) > 1:
        velocities = gaussian_filter1d(velocities, TRANSITION_SIGMA * fps, axis=0, mode="nearest")
    return PathControl(velocities, fps, description.get("name", "synthetic"))


PRESETS: dict[str, dict] = {
    "walk-straight": {"segments": [{"type": "straight", "speed": 120, "seconds": 4}]},
    "run-straight": {"segments": [{"type": "straight", "speed": 300, "seconds": 4}]},
    "walk-circle": {"segments": [{"type": "curve", "speed": 110, "turn_rate": 45, "seconds": 4}]},
    "walk-zigzag": {"segments": [{"type": "curve", "speed": 110, "turn_rate": 40, "seconds": 1.5},
                                 {"type": "curve", "speed": 110, "turn_rate": -40, "seconds": 1.5},
                                 {"type": "curve", "speed": 110, "turn_rate": 40, "seconds": 1}]},
    "sidestep-left": {"segments": [{"type": "sidestep", "direction": "left", "speed": 60, "seconds": 4}]},
    "sidestep-right": {"segments": [{"type": "sidestep", "direction": "right", "speed": 60, "seconds": 4}]},
    "walk-backward": {"segments": [{"type": "backward", "speed": 90, "seconds": 4}]},
    "stand-still": {"segments": [{"type": "stand", "seconds": 4}]},
    "walk-stop-walk": {"segments": [{"type": "straight", "speed": 120, "seconds": 1.5},
                                    {"type": "stand", "seconds": 1.5},
                                    {"type": "straight", "speed": 120, "seconds": 1.5}]},
    "speed-ramp": {"segments": [{"type": "ramp", "from": 0, "to": 300, "seconds": 4}]},
}


def preset_path(name: str, fps: float = 20.0) -> PathControl:
    """One of the named synthetic paths (``PRESETS``)."""
    if name not in PRESETS:
        raise ValueError(f"unknown control preset {name!r}; choose from {', '.join(PRESETS)}")
    return synthetic_path({"name": name, **PRESETS[name]}, fps)


def load_control_file(path: str | Path, fps: float = 20.0) -> list[PathControl]:
    """Synthetic paths from a JSON or YAML file: one description, or a list of them."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not UTF-8 text (byte {error.start})") from None
    try:  # both parsers recurse per level: thousands of nested brackets exhaust the stack
        if path.suffix.lower() in (".yaml", ".yml"):
            try:
                data = yaml.safe_load(text)
            except yaml.YAMLError as error:
                raise ValueError(f"{path}: invalid YAML ({error})") from None
        else:
            try:
                data = json.loads(text)
            except json.JSONDecodeError as error:
                raise ValueError(f"{path}:{error.lineno}: invalid JSON ({error.msg})") from None
    except RecursionError:
        raise ValueError(f"{path}: nested too deeply to be a path description") from None
    return described_paths(data, str(path), path.stem, fps)


def described_paths(data: object, source: str, stem: str, fps: float = 20.0) -> list[PathControl]:
    """Synthetic paths from a read control file's value (one description, or a list of them),
    named ``stem-0``, ``stem-1``, ...; a ValueError naming ``source`` and the path for a wrong one."""
    descriptions = data if isinstance(data, list) else [data]
    controls = []
    for i, description in enumerate(descriptions):
        try:
            controls.append(synthetic_path({"name": f"{stem}-{i}", **description}, fps))
        except (ValueError, TypeError, AttributeError) as error:
            raise ValueError(f"{source}: path {i}: {error}") from None
    return controls


def in_control_frame(motion: Motion, root: RootOptions = RootOptions()) -> Motion:
    """``motion`` moved on the floor so that its root starts at the origin facing +z, where
    every control's path starts: a natural take then walks along its own control's
    path, and any clip can be drawn over any control's path (``render_video``'s
    ``control_path``). Generated motion starts there already."""
    start = root_trajectory(motion, root)
    positions = motion.positions.copy()
    floor = to_root_frame(positions[..., [0, 2]] - start.xz[0], start.yaw[0])
    positions[..., 0], positions[..., 2] = floor[..., 0], floor[..., 1]
    return Motion(positions, motion.fps, motion.skeleton)


def following_arrays(motion: Motion, asked: RootTrajectory, root: RootOptions = RootOptions()) -> dict[str, np.ndarray]:
    """The arrays beside a clip that ``analysis``'s control-adherence metrics read
    (analysis/motion/motion_io.py): the path and facing the clip was asked to follow
    (``asked``, in the clip's floor coordinates) and where its root went and faced."""
    went = root_trajectory(motion, root)
    return {"control_path": asked.xz, "control_yaw": asked.yaw, "root_path": went.xz, "root_yaw": went.yaw}


def held_out_paths(dataset, seconds: float | None = None, lead_in_seconds: float = 0.0) -> list[PathControl]:
    """The control of each held-out natural clip of a dataset (``take_paths``)."""
    takes = [(clip.name, dataset.clip_arrays(clip)["control"]) for clip in dataset.select("test")]
    return take_paths(takes, dataset.options.fps, seconds, lead_in_seconds)


def take_paths(takes: Iterable[tuple[str, np.ndarray]], fps: float, seconds: float | None = None,
               lead_in_seconds: float = 0.0) -> list[PathControl]:
    """The control of each natural take, given as (name, per-frame control), cut to
    ``seconds``; takes too short for two frames are left out.

    With ``lead_in_seconds`` each clip starts that far into its take, and the take's
    control before it is the clip's lead-in: sampling then warms up on the take's own
    start, as the MoGlow authors' code samples a test take from its first frame.
    """
    frames = _frames_of(seconds, fps)
    lead = lead_in_frames(lead_in_seconds, fps)
    result = []
    for name, control in takes:
        take = np.asarray(control, dtype=np.float64)
        clip = take[lead:] if frames is None else take[lead:lead + frames]
        if len(clip) >= 2:
            result.append(PathControl(clip, fps, name, take[:lead] if lead else None))
    return result


def shorter_than_asked(controls: Iterable[Control], seconds: float | None) -> list[Control]:
    """The controls cut to ``seconds`` (``take_paths``, ``take_attributes``) that last less,
    their take ending sooner: a clip of another length than asked, which must say so."""
    if seconds is None:
        return []
    return [control for control in controls if control.n_frames < _frames_of(seconds, control.fps)]


def length_warning(control: Control, seconds: float) -> str:
    """What a control shorter than the ``seconds`` asked tells the researcher."""
    return (f"{control.name} lasts {control.n_frames / control.fps:.2f} s ({control.n_frames} frames), not the "
            f"{seconds:g} s asked: its take ends sooner")


def lead_in_frames(seconds: float, fps: float) -> int:
    """A lead-in of ``seconds`` (0 for none) as a number of frames, refusing what no take lasts."""
    if not (math.isfinite(seconds) and 0 <= seconds <= MAX_PATH_SECONDS):
        raise ValueError(f"the lead-in must be 0 or more seconds and at most {MAX_PATH_SECONDS:g}, got {seconds}")
    return int(round(seconds * fps))


def held_out_attributes(dataset, seconds: float | None = None) -> list[AttributeControl]:
    """The action and style labels of each labelled held-out natural clip of a dataset
    (``take_attributes``)."""
    takes = [(clip.name, clip.content, clip.style, clip.stop - clip.start)
             for clip in dataset.select("test", augmented=False)]
    return take_attributes(takes, dataset.options.fps, seconds)


def take_attributes(takes: Iterable[tuple[str, str | None, str | None, int]], fps: float,
                    seconds: float | None = None) -> list[AttributeControl]:
    """The action and style labels of each labelled natural take, given as (name, content,
    style, frames), for as long as the take lasts (or ``seconds``, if shorter): what a
    label-controlled model is asked to do where the take shows what a person did."""
    longest = _frames_of(seconds, fps)
    return [AttributeControl(content, style, frames if longest is None else min(frames, longest), fps, name)
            for name, content, style, frames in takes if content is not None and style is not None]
