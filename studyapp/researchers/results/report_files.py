"""A report's folder as one zip, for the researcher who made it: the summary, every table
in each of its formats, the figures, and the ratings and rules it was made from (its
owner's record, ``owner.txt``, stays on the server)."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

from studyapp.researchers.results.reports import OWNER_NAME, report_folder, report_owner


def report_zip(media_root: Path, digest: str, owner_id: int) -> bytes:
    """The zip of report ``digest``; FileNotFoundError for another researcher's report, as if it did not exist."""
    folder = report_folder(media_root, digest)
    if report_owner(media_root, digest) != owner_id:
        raise FileNotFoundError(digest)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(p for p in folder.rglob("*") if p.is_file() and p.name != OWNER_NAME):
            archive.write(path, f"report-{digest[:12]}/{path.relative_to(folder).as_posix()}")
    return buffer.getvalue()


__all__ = ["report_zip"]
