"""The gallery of rendered natural motion clips that `make demo` writes to media.

The demo renders clips to `MEDIA_ROOT/gallery/*.mp4` and lists them in
`MEDIA_ROOT/gallery/index.json`, a JSON list of objects with `file`, `title`,
`content`, `style`, `frames`, `fps`, an optional contact-sheet `sheet` and an optional
`poster` (the first frame, which the page shows before a video plays).
"""

import json
from dataclasses import dataclass
from pathlib import Path

GALLERY_FOLDER = "gallery"
INDEX_NAME = "index.json"


class GalleryIndexError(ValueError):
    """The index exists but cannot be read as a list of clips."""


@dataclass(frozen=True)
class GalleryClip:
    file: str
    title: str
    content: str
    style: str
    frames: int
    fps: float
    sheet: str | None = None
    poster: str | None = None  # the first frame, shown before the video plays

    @property
    def seconds(self) -> float:
        return self.frames / self.fps if self.fps else 0.0


def index_path(media_root: Path) -> Path:
    return media_root / GALLERY_FOLDER / INDEX_NAME


def _clip_from_entry(entry: object, position: int) -> GalleryClip:
    if not isinstance(entry, dict):
        raise GalleryIndexError(f"entry {position} is not an object")
    try:
        return GalleryClip(
            file=str(entry["file"]),
            title=str(entry.get("title") or entry["file"]),
            content=str(entry.get("content", "")),
            style=str(entry.get("style", "")),
            frames=int(entry.get("frames", 0)),
            fps=float(entry.get("fps", 0)),
            sheet=str(entry["sheet"]) if entry.get("sheet") else None,
            poster=str(entry["poster"]) if entry.get("poster") else None,
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise GalleryIndexError(f"entry {position}: {type(exc).__name__}: {exc}") from exc


def load_gallery(media_root: Path) -> list[GalleryClip] | None:
    """The clips listed in the index, or None when the gallery has not been built."""
    path = index_path(media_root)
    try:
        entries = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, json.JSONDecodeError) as exc:
        raise GalleryIndexError(f"{path}: {exc}") from exc
    if not isinstance(entries, list):
        raise GalleryIndexError(f"{path}: expected a JSON list of clips")
    return [_clip_from_entry(entry, position) for position, entry in enumerate(entries)]
