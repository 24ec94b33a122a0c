"""Read and write BVH motion capture files, for any skeleton.

Supports any number of position and rotation channels per joint, any rotation order,
End Sites, tabs or spaces, and any frame rate. Errors name the file and the line.

Convention for position channels: a joint's animated position channels replace its
OFFSET on the axes they cover (as most exporters, including the Bandai-Namco data, write
the offset itself into non-root position channels).

Units: the format states none. Files are read in their own unit and converted by the
caller's scale (``units``); motion is written in centimetres unless another unit is
asked for (``motion_to_bvh(..., unit=)``), and the writer says which unit it used.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from measures.units import UNITS, Z_UP_TO_Y_UP

from ..files import write_atomic
from .ik import with_rotations
from .kinematics import forward_kinematics
from .rotations import euler_to_matrix, matrix_to_continuous_euler, matrix_to_quat, quat_to_matrix
from .types import Motion, Skeleton
from .skeleton_units import Units

POSITION_AXIS = {"Xposition": 0, "Yposition": 1, "Zposition": 2}
ROTATION_AXIS = {"Xrotation": "X", "Yrotation": "Y", "Zrotation": "Z"}
# Frame times outside these are no motion capture (10,000 to 0.1 frames per second); a
# 1e-320 s frame has no frame rate a float can hold, and a 1e6 s one would have the
# renderer draw days of video from two frames.
MIN_FRAME_TIME, MAX_FRAME_TIME = 1e-4, 10.0
MAX_INDENT = 32  # tabs
# No length in any unit nor any angle in degrees comes near this; 1e308 would overflow
# to infinity in the first sum of forward kinematics.
MAX_ABS_VALUE = 1e9


class BVHError(ValueError):
    """A BVH file that cannot be read; the message names the file and line."""

    def __init__(self, path: str | os.PathLike, message: str, line: int | None = None):
        where = f"{path}:{line}" if line is not None else str(path)
        super().__init__(f"{where}: {message}")
        self.path, self.line = str(path), line


@dataclass(frozen=True)
class BVH:
    """The contents of a BVH file: hierarchy, channel layout and raw channel values.

    ``values`` is (frames, channels) exactly as in the file (cm or the file's unit,
    degrees). ``channels[j]`` lists joint j's channel names in file order.
    """

    skeleton: Skeleton
    channels: tuple[tuple[str, ...], ...]
    frame_time: float
    values: np.ndarray

    @property
    def fps(self) -> float:
        """Frames per second; snapped to an integer when the file rounds its frame time."""
        return frame_rate(self.frame_time)

    def channel_columns(self) -> list[range]:
        """The columns of ``values`` that belong to each joint."""
        columns, start = [], 0
        for names in self.channels:
            columns.append(range(start, start + len(names)))
            start += len(names)
        return columns

    def to_motion(self, scale: float = 1.0, up: str = "y") -> Motion:
        """Joint rotations, translations and (by forward kinematics) positions, in
        centimetres with y up.

        ``scale`` converts the file's length unit to centimetres (e.g. 100 for metres);
        ``up`` is the file's vertical axis ("y" or "z"), turned into y by rotating the root.
        """
        Units(scale, up)  # validates both
        n_frames, n_joints = len(self.values), self.skeleton.n_joints
        rotations = np.empty((n_frames, n_joints, 3, 3))
        translations = np.broadcast_to(self.skeleton.offsets, (n_frames, n_joints, 3)).copy()
        # Joints that share a rotation order are converted in one vectorised call.
        by_order: dict[str, tuple[list[int], list[list[int]]]] = {}
        for j, (names, cols) in enumerate(zip(self.channels, self.channel_columns())):
            order = "".join(ROTATION_AXIS[c] for c in names if c in ROTATION_AXIS)
            joints, columns = by_order.setdefault(order, ([], []))
            joints.append(j)
            columns.append([col for c, col in zip(names, cols) if c in ROTATION_AXIS])
            for c, col in zip(names, cols):
                if c in POSITION_AXIS:
                    translations[:, j, POSITION_AXIS[c]] = self.values[:, col]
        for order, (joints, columns) in by_order.items():
            angles = np.radians(self.values[:, columns])  # (frames, joints, len(order))
            rotations[:, joints] = euler_to_matrix(angles, order)
        translations *= scale
        if up == "z":
            rotations[:, 0] = Z_UP_TO_Y_UP @ rotations[:, 0]
            translations[:, 0] = translations[:, 0] @ Z_UP_TO_Y_UP.T
        skeleton = self.skeleton
        if scale != 1.0:
            skeleton = Skeleton(
                skeleton.names,
                skeleton.parents,
                skeleton.offsets * scale,
                {j: o * scale for j, o in skeleton.end_sites.items()},
            )
        positions = forward_kinematics(rotations, translations, skeleton.parents)
        return Motion(
            positions=positions,
            fps=self.fps,
            skeleton=skeleton,
            rotations=matrix_to_quat(rotations),
            translations=translations,
        )


def _bvh_path(path: str | os.PathLike) -> Path:
    path = Path(path)
    if path.is_dir():
        raise BVHError(path, "is a folder, not a BVH file")
    return path


@contextmanager
def _reading(path: Path) -> Iterator[None]:
    """A file that cannot be read as text is a BVHError naming it, as a malformed one is."""
    try:
        yield
    except FileNotFoundError:
        raise BVHError(path, "no such file") from None
    except UnicodeDecodeError as error:
        raise BVHError(path, f"not a text file ({error.reason})") from None
    except OSError as error:
        raise BVHError(path, f"cannot be read ({error.strerror or error})") from None


def read_bvh(path: str | os.PathLike) -> BVH:
    """Parse a BVH file. Raises BVHError naming the file and line on malformed input."""
    path = _bvh_path(path)
    with _reading(path):
        text = path.read_text()
    lines = text.splitlines()
    skeleton, channels, motion_line = _parse_hierarchy(path, lines)
    frame_time, values = _parse_motion(path, lines, motion_line, sum(map(len, channels)))
    return BVH(skeleton, channels, frame_time, values)


def _header_lines(path: Path) -> list[str]:
    """The lines up to the MOTION section's 'Frame Time:' (all of them if there is none):
    the hierarchy and the frame count and rate, without the rows of values."""
    lines, in_motion = [], False
    with _reading(path), open(path) as f:
        for raw in f:
            lines.append(raw)
            in_motion = in_motion or raw.split()[:1] == ["MOTION"]
            if in_motion and raw.strip().startswith("Frame Time"):
                break
    return lines


def bvh_duration(path: str | os.PathLike) -> float:
    """Seconds of motion a BVH file declares, read from its header only. The header is
    held to ``read_bvh``'s rules (BVHError naming the file and line); the rows of values
    are not read."""
    path = _bvh_path(path)
    lines = _header_lines(path)
    _, _, motion_line = _parse_hierarchy(path, lines)
    n_frames, frame_time, _ = _motion_header(path, lines, motion_line)
    return n_frames * frame_time


def frame_rate(frame_time: float) -> float:
    """Frames per second of a frame time; snapped to an integer when a file rounds its frame time."""
    fps = 1.0 / frame_time
    return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else fps


def bvh_frame_rate(path: str | os.PathLike) -> float:
    """Frames per second a BVH file declares, read from its header only (as ``bvh_duration``)."""
    path = _bvh_path(path)
    lines = _header_lines(path)
    _, _, motion_line = _parse_hierarchy(path, lines)
    return frame_rate(_motion_header(path, lines, motion_line)[1])


def load_motion(path: str | os.PathLike, scale: float = 1.0, up: str = "y") -> Motion:
    """Read a BVH file straight into a Motion (positions by forward kinematics), in
    centimetres with y up (see ``BVH.to_motion``)."""
    return read_bvh(path).to_motion(scale, up)


def read_bvh_skeleton(path: str | os.PathLike) -> Skeleton:
    """The skeleton of a BVH file, read from its hierarchy only (fast on long files)."""
    path = _bvh_path(path)
    return _parse_hierarchy(path, _header_lines(path))[0]


def _floats(path: Path, tokens: list[str], count: int, what: str, line: int) -> list[float]:
    if len(tokens) != count:
        raise BVHError(path, f"{what} needs {count} numbers, found {len(tokens)}", line)
    try:
        numbers = [float(t) for t in tokens]
    except ValueError:
        raise BVHError(path, f"{what} has a non-numeric value: {' '.join(tokens)!r}", line) from None
    if not all(math.isfinite(x) for x in numbers):
        raise BVHError(path, f"{what} has a NaN or infinite value", line)
    if any(abs(x) > MAX_ABS_VALUE for x in numbers):
        raise BVHError(path, f"{what} has a value beyond ±{MAX_ABS_VALUE:g}", line)
    return numbers


def _parse_hierarchy(path: Path, lines: list[str]):
    """Parse up to the MOTION line. Returns (skeleton, channels, index of MOTION line)."""
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float] | None] = []
    channels: list[tuple[str, ...]] = []
    end_sites: dict[int, list[list[float]]] = {}
    stack: list[tuple[str, int]] = []  # ("joint", j) or ("end", j) for open blocks
    pending: tuple[str, int] | None = None  # declared, waiting for its "{"
    seen_header = False

    for i, raw in enumerate(lines):
        tokens = raw.split()
        if not tokens:
            continue
        line, keyword = i + 1, tokens[0]
        if not seen_header:
            if keyword != "HIERARCHY":  # nothing of it is repeated: it may be any file, a secret one among them
                raise BVHError(path, "not a BVH file (it does not start with HIERARCHY)", line)
            seen_header = True
            continue
        if pending is not None and keyword != "{":
            raise BVHError(path, f"expected '{{' after the {pending[0]} declaration", line)
        if keyword in ("ROOT", "JOINT"):
            if len(tokens) < 2:
                raise BVHError(path, f"{keyword} without a name", line)
            if keyword == "ROOT" and names:
                raise BVHError(path, "a second ROOT; only one skeleton per file is supported", line)
            if keyword == "JOINT" and not (stack and stack[-1][0] == "joint"):
                raise BVHError(path, "JOINT outside a joint block", line)
            name = " ".join(tokens[1:])
            if name in names:
                raise BVHError(path, f"duplicate joint name {name!r}", line)
            parents.append(stack[-1][1] if stack else -1)
            names.append(name)
            offsets.append(None)
            channels.append(())
            pending = ("joint", len(names) - 1)
        elif keyword == "End":
            if not (stack and stack[-1][0] == "joint"):
                raise BVHError(path, "End Site outside a joint block", line)
            pending = ("end", stack[-1][1])
            end_sites.setdefault(stack[-1][1], []).append([0.0, 0.0, 0.0])
        elif keyword == "{":
            if pending is None:
                raise BVHError(path, "unexpected '{'", line)
            stack.append(pending)
            pending = None
        elif keyword == "}":
            if not stack:
                raise BVHError(path, "unmatched '}'", line)
            kind, j = stack.pop()
            if kind == "joint" and offsets[j] is None:
                raise BVHError(path, f"joint {names[j]!r} has no OFFSET", line)
        elif keyword == "OFFSET":
            if not stack:
                raise BVHError(path, "OFFSET outside a block", line)
            offset = _floats(path, tokens[1:], 3, "OFFSET", line)
            kind, j = stack[-1]
            if kind == "joint":
                offsets[j] = offset
            else:
                end_sites[j][-1] = offset
        elif keyword == "CHANNELS":
            if not (stack and stack[-1][0] == "joint"):
                raise BVHError(path, "CHANNELS outside a joint block", line)
            try:
                count = int(tokens[1])
            except (IndexError, ValueError):
                raise BVHError(path, "CHANNELS needs a count", line) from None
            found = tokens[2:]
            if len(found) != count:
                raise BVHError(path, f"CHANNELS declares {count} channels but names {len(found)}", line)
            for name in found:
                if name not in POSITION_AXIS and name not in ROTATION_AXIS:
                    raise BVHError(path, f"unknown channel name {name!r}", line)
            if len(set(found)) != len(found):
                raise BVHError(path, "a channel is listed twice", line)
            channels[stack[-1][1]] = tuple(found)
        elif keyword == "MOTION":
            if stack or pending:
                raise BVHError(path, "MOTION before the hierarchy's blocks are closed", line)
            if not names:
                raise BVHError(path, "the hierarchy has no ROOT", line)
            if not any(channels):
                raise BVHError(path, "no joint has channels (every CHANNELS is 0 or missing): "
                                     "the file can hold no motion", line)
            skeleton = Skeleton(
                names=tuple(names),
                parents=np.asarray(parents),
                offsets=np.asarray(offsets, dtype=np.float64),
                end_sites={j: np.asarray(o, dtype=np.float64) for j, o in end_sites.items()},
            )
            return skeleton, tuple(channels), i
        else:
            raise BVHError(path, f"unknown keyword {keyword!r}", line)
    what = "the file is empty" if not seen_header else "the file ends before its MOTION section"
    raise BVHError(path, what, len(lines) if lines else None)


def _motion_header(path: Path, lines: list[str], motion_line: int) -> tuple[int, float, int]:
    """The MOTION section's frame count and frame time, and the index of the first row."""
    header: dict[str, str] = {}
    header_line: dict[str, int] = {}
    row_start = len(lines)
    for i in range(motion_line + 1, len(lines)):
        stripped = lines[i].strip()
        if not stripped:
            continue
        key, _, value = stripped.partition(":")
        if key in ("Frames", "Frame Time") and key not in header:
            header[key], header_line[key] = value.strip(), i + 1
            if len(header) == 2:
                row_start = i + 1
                break
        else:
            raise BVHError(path, f"expected 'Frames:' and 'Frame Time:', found {stripped[:40]!r}", i + 1)
    if len(header) < 2:
        raise BVHError(path, "the MOTION section lacks 'Frames:' or 'Frame Time:'", len(lines))
    try:
        n_frames, frame_time = int(header["Frames"]), float(header["Frame Time"])
    except ValueError:
        raise BVHError(path, "'Frames:' or 'Frame Time:' is not a number", row_start) from None
    if n_frames <= 0:
        raise BVHError(path, f"the file declares {n_frames} frames; a motion needs at least one", header_line["Frames"])
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise BVHError(path, f"Frame Time must be positive, found {frame_time}", header_line["Frame Time"])
    if not MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
        raise BVHError(path, f"Frame Time {header['Frame Time']} s is outside {MIN_FRAME_TIME:g} to "
                             f"{MAX_FRAME_TIME:g} s ({1 / MIN_FRAME_TIME:g} to {1 / MAX_FRAME_TIME:g} frames per second)",
                       header_line["Frame Time"])
    return n_frames, frame_time, row_start


def _parse_motion(path: Path, lines: list[str], motion_line: int, n_channels: int):
    """Parse the MOTION section: frame count, frame time and the value rows."""
    n_frames, frame_time, row_start = _motion_header(path, lines, motion_line)
    row_lines = [i for i in range(row_start, len(lines)) if lines[i].strip()]
    rows = [lines[i] for i in row_lines]
    if len(rows) < n_frames:
        raise BVHError(
            path, f"truncated: 'Frames: {n_frames}' but only {len(rows)} rows of values",
            len(lines),
        )
    if len(rows) > n_frames:
        raise BVHError(
            path, f"'Frames: {n_frames}' but {len(rows)} rows of values", row_lines[n_frames] + 1
        )
    tokens = " ".join(rows).split()
    try:
        values = np.array(tokens, dtype=np.float64) if len(tokens) == n_frames * n_channels else None
    except ValueError:
        values = None
    if values is None or not (np.abs(values) <= MAX_ABS_VALUE).all():  # NaN fails the comparison too
        _raise_for_bad_row(path, rows, row_lines, n_channels)
    return frame_time, values.reshape(n_frames, n_channels)


def _raise_for_bad_row(path: Path, rows: list[str], row_lines: list[int], n_channels: int):
    """Slow path: find the first bad row and say what is wrong with it."""
    for row, i in zip(rows, row_lines):
        _floats(path, row.split(), n_channels, "the frame row", i + 1)
    raise AssertionError("unreachable: a bad row was expected")


def _format_number(x: float) -> str:
    text = f"{x:.9g}"
    return "0" if text == "-0" else text


def bvh_text(bvh: BVH) -> str:
    """The BVH file contents for ``bvh`` (tab-indented, numbers to 9 significant digits)."""
    skeleton, out = bvh.skeleton, ["HIERARCHY"]
    children: dict[int, list[int]] = {j: [] for j in range(skeleton.n_joints)}
    for j, p in enumerate(skeleton.parents):
        if p >= 0:
            children[int(p)].append(j)

    def vector(v) -> str:
        return " ".join(_format_number(x) for x in v)

    # Depth-first with a stack of its own: a chain of thousands of joints is legal BVH and
    # would exceed Python's recursion limit. An entry is a joint to open or a line to close it.
    # Indentation is only for reading, and stops deepening where a reader would stop counting.
    pending: list[tuple[int, int] | str] = [(0, 0)]
    while pending:
        item = pending.pop()
        if isinstance(item, str):
            out.append(item)
            continue
        j, depth = item
        tab = "\t" * min(depth, MAX_INDENT)
        out.append(f"{tab}{'ROOT' if depth == 0 else 'JOINT'} {skeleton.names[j]}")
        out.append(f"{tab}{{")
        out.append(f"{tab}\tOFFSET {vector(skeleton.offsets[j])}")
        if bvh.channels[j]:
            out.append(f"{tab}\tCHANNELS {len(bvh.channels[j])} {' '.join(bvh.channels[j])}")
        closing = []
        for site in np.asarray(skeleton.end_sites.get(j, np.empty((0, 3)))).reshape(-1, 3):
            closing += [f"{tab}\tEnd Site", f"{tab}\t{{", f"{tab}\t\tOFFSET {vector(site)}", f"{tab}\t}}"]
        closing.append(f"{tab}}}")
        # Popped in reverse: the children in order, then the End Sites and the closing brace.
        pending += [*reversed(closing), *[(child, depth + 1) for child in reversed(children[j])]]

    out += ["MOTION", f"Frames: {len(bvh.values)}", f"Frame Time: {bvh.frame_time:.9g}"]
    out += [vector(row) for row in bvh.values]
    return "\n".join(out) + "\n"


def write_bvh(bvh: BVH, path: str | os.PathLike) -> Path:
    """Write ``bvh`` atomically: the file appears whole or not at all."""
    path = Path(path)
    write_atomic(path, bvh_text(bvh).encode())
    return path


def scale_lengths(bvh: BVH, factor: float) -> BVH:
    """The same motion with every length (OFFSETs, End Sites, position channels)
    multiplied by ``factor``: the file in another unit. Angles are unchanged."""
    values = bvh.values.copy()
    for names, columns in zip(bvh.channels, bvh.channel_columns()):
        for name, column in zip(names, columns):
            if name in POSITION_AXIS:
                values[:, column] *= factor
    skeleton = Skeleton(bvh.skeleton.names, bvh.skeleton.parents, bvh.skeleton.offsets * factor,
                        {j: o * factor for j, o in bvh.skeleton.end_sites.items()})
    return BVH(skeleton, bvh.channels, bvh.frame_time, values)


def motion_to_bvh(motion: Motion, rotation_order: str = "ZXY", unit: str = "cm") -> BVH:
    """A rotation BVH for any motion, its lengths in ``unit`` (a key of
    ``measures.units.UNITS``; the motion itself is in centimetres).

    Every joint gets rotation channels in ``rotation_order`` (the Bandai-Namco rigs'
    own, ZXY, by default), its angles continuous over time
    (``rotations.matrix_to_continuous_euler``), and joints whose translation is animated
    (the root) also get position channels. A position-only motion (MoGlow and its
    baselines) gets its rotations by inverse kinematics on its skeleton first
    (``ik.with_rotations``): the file holds the rig's bone lengths, every bone pointing
    where the motion's does.
    """
    if unit not in UNITS:
        raise ValueError(f"BVH unit must be one of {', '.join(UNITS)}, got {unit!r}")
    bvh = _motion_to_bvh_cm(motion, rotation_order)
    return bvh if unit == "cm" else scale_lengths(bvh, 1.0 / UNITS[unit])


def _motion_to_bvh_cm(motion: Motion, rotation_order: str) -> BVH:
    motion = with_rotations(motion)
    offsets = motion.skeleton.offsets
    channels, columns = [], []
    euler = np.degrees(matrix_to_continuous_euler(quat_to_matrix(motion.rotations), rotation_order))
    for j in range(motion.skeleton.n_joints):
        translation = motion.translations[:, j]
        animated = j == 0 or not np.allclose(translation, offsets[j], atol=1e-6)
        names = (["Xposition", "Yposition", "Zposition"] if animated else [])
        names += [f"{axis}rotation" for axis in rotation_order]
        channels.append(tuple(names))
        if animated:
            columns.append(translation)
        columns.append(euler[:, j])
    values = np.concatenate(columns, axis=1)
    return BVH(motion.skeleton, tuple(channels), 1.0 / motion.fps, values)
