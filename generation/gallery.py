"""A gallery of natural clips: videos, their posters (the first frame, shown before a
video plays), contact sheets and an index for the web page.

The index (``index.json``) lists one entry per clip: file, title, content, style, frames,
fps, sheet and poster. The study app's gallery page reads it. No clip is shorter than
``GalleryOptions.min_seconds``: too short to see a motion in, it is left out.

Every clip is drawn on one display figure, as a study's clips are
(``generation.render.retarget``): the bone lengths of the first clip the gallery draws
(the reference skeleton of its natural data), its feet on the floor. Its description
travels in the options (``GalleryOptions.figure``), so each worker draws the same figure;
options without one draw each clip on the figure of its own skeleton's lengths.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

from tqdm import tqdm

from .files import write_atomic
from .motion.bvh import bvh_duration
from .motion.clip_files import content_matches, find_bvh_files, load_body_motion, read_labels
from .motion.root import RootOptions, root_trajectory
from .motion.unit_detection import choose_units
from .motion.types import Motion
from .render import Camera, contact_sheet, render_video
from .render.display_figure import DisplayFigure, complete_mapping, mapping_pose
from .render.retarget import retarget


@dataclass(frozen=True)
class GalleryOptions:
    fps: float = 20.0
    seconds: float = 4.0  # each clip is cut to at most this long, from its start
    min_seconds: float = 1.0  # takes shorter than this are left out
    size: tuple[int, int] = (640, 480)
    per_content: int = 1  # clips per content label
    contents: tuple[str, ...] | None = None
    camera: Camera = Camera()
    scale: float | None = None  # the files' unit in cm; None: detected
    up: str | None = None  # the files' up axis; None: detected
    figure: DisplayFigure | None = None  # what every clip is drawn on; None: each clip's own lengths

    def to_dict(self) -> dict:
        """JSON-serialisable, to send to a worker."""
        return {
            "fps": self.fps, "seconds": self.seconds, "min_seconds": self.min_seconds, "size": list(self.size),
            "per_content": self.per_content,
            "contents": list(self.contents) if self.contents is not None else None,
            "camera": self.camera.to_dict(), "scale": self.scale, "up": self.up,
            "figure": self.figure.to_dict() if self.figure is not None else None,
        }

    @classmethod
    def from_dict(cls, data: dict) -> "GalleryOptions":
        return cls(
            fps=data["fps"], seconds=data["seconds"], min_seconds=data.get("min_seconds", 0.0), size=tuple(data["size"]),
            per_content=data["per_content"],
            contents=tuple(data["contents"]) if data["contents"] is not None else None,
            camera=Camera.from_dict(data["camera"]), scale=data.get("scale"), up=data.get("up"),
            figure=DisplayFigure.from_dict(data["figure"]) if data.get("figure") is not None else None,
        )


def choose_clips(folder: str | os.PathLike, per_content: int, contents: tuple[str, ...] | None,
                 seconds: float = 0.0, min_seconds: float = 0.0) -> list[Path]:
    """The first ``per_content`` clips (by name) of each content label, none shorter than
    ``min_seconds``: clips lasting at least ``seconds`` first (the "normal" style first
    among them), then the longest."""
    chosen: dict[str | None, list[Path]] = {}
    durations = {p: bvh_duration(p) for p in find_bvh_files(folder)}
    labels = {p: read_labels(p) for p, duration in durations.items() if duration >= min_seconds}
    files = sorted(labels, key=lambda p: (-min(durations[p], seconds), labels[p][1] != "normal", p.name))
    for path in files:
        content = labels[path][0]
        if contents is not None and not any(content_matches(content, c) for c in contents):
            continue
        group = chosen.setdefault(content, [])
        if len(group) < per_content:
            group.append(path)
    return sorted(p for group in chosen.values() for p in group)


def load_clip(path: Path, options: GalleryOptions) -> Motion:
    """The clip as the gallery reads it: at its fps, cut to its seconds, in cm with y up."""
    units = choose_units([path], options.scale, options.up).units
    return load_body_motion(path, options.fps, options.seconds, units.scale, up=units.up)


def figure_of(motion: Motion) -> DisplayFigure:
    """The display figure with ``motion``'s bone lengths, its joints mapped by their names and shape."""
    return DisplayFigure.of_motion(motion, complete_mapping(motion.skeleton, mapping_pose(motion)))


def with_figure(options: GalleryOptions, clips: list[Path]) -> GalleryOptions:
    """``options`` drawing every clip on the figure of the first of ``clips`` (where they
    name no figure and there is a clip)."""
    if options.figure is not None or not clips:
        return options
    return replace(options, figure=figure_of(load_clip(clips[0], options)))


def render_clip(path: Path, out_dir: Path, options: GalleryOptions) -> dict:
    """Render one BVH clip (video, poster and contact sheet) on the options' display figure
    unless already there; its index entry."""
    video, sheet, poster = out_dir / f"{path.stem}.mp4", out_dir / f"{path.stem}.png", out_dir / f"{path.stem}.poster.png"
    motion = load_clip(path, options)
    floor = root_trajectory(motion, RootOptions()).xz
    motion = retarget(motion, complete_mapping(motion.skeleton, mapping_pose(motion)), options.figure or figure_of(motion))
    if not video.exists():
        render_video(motion, video, camera=options.camera, size=options.size, root_path=floor)
    if not sheet.exists():
        contact_sheet(motion, sheet, n=8, camera=options.camera, root_path=floor)
    if not poster.exists():  # the video's first frame, at its size
        contact_sheet(motion, poster, n=1, camera=options.camera, size=options.size, root_path=floor)
    content, style = read_labels(path)
    return {
        "file": video.name,
        "title": " / ".join(x for x in (content, style, path.stem.rsplit("_", 1)[-1]) if x),
        "content": content,
        "style": style,
        "frames": motion.n_frames,
        "fps": motion.fps,
        "sheet": sheet.name,
        "poster": poster.name,
        "source": path.name,
    }


def write_index(out_dir: str | os.PathLike, entries: list[dict]) -> Path:
    """Write the gallery's ``index.json`` (atomically)."""
    path = Path(out_dir) / "index.json"
    write_atomic(path, json.dumps(entries, indent=2).encode())
    return path


def build_gallery(folder: str | os.PathLike, out_dir: str | os.PathLike, options: GalleryOptions = GalleryOptions(), progress: bool = True) -> list[dict]:
    """Render the chosen clips into ``out_dir`` and write its ``index.json``; units the
    options leave open are detected for all the clips together (and printed)."""
    out_dir = Path(out_dir)
    clips = choose_clips(folder, options.per_content, options.contents, options.seconds, options.min_seconds)
    if clips and (options.scale is None or options.up is None):
        choice = choose_units(clips, options.scale, options.up)
        options = replace(options, scale=choice.units.scale, up=choice.units.up)
        if progress:
            print(choice.description)
    options = with_figure(options, clips)
    entries = [render_clip(p, out_dir, options) for p in tqdm(clips, desc="rendering gallery", unit="clip", disable=not progress)]
    write_index(out_dir, entries)
    return entries
