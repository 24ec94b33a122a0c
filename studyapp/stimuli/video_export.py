"""Every finished clip of a study as an MP4 in one zip, for the researcher's own viewing,
a supplement or a talk:

    stimuli-study-<pk>/<system>/<control id>.mp4   named as the motion export names its files
                                                   (an uploaded video: video-<id>.mp4)
    stimuli-study-<pk>/index.csv                   file, system, control, control_class and the
                                                   stimulus column of the ratings table

The videos are stored as they are (an MP4 does not compress further) into a temporary
file, which the download streams and deletes.
"""

from __future__ import annotations

import csv
import io
import tempfile
import zipfile
from typing import IO

from studyapp.models import Stimulus, Study
from studyapp.stimuli.motion_export import clip_name, folder_name


def finished_clips(study: Study) -> list[Stimulus]:
    return list(study.stimuli.filter(status=Stimulus.Status.DONE).select_related("system", "control")
                .order_by("system__name", "control__name", "seed", "pk"))


def stimuli_zip(study: Study) -> IO[bytes]:
    """A temporary file (deleted when closed) holding the zip, at its start.

    FileNotFoundError naming the clip where a finished clip's video is missing.
    """
    top = f"stimuli-study-{study.pk}"
    index = io.StringIO()
    rows = csv.writer(index, lineterminator="\n")
    rows.writerow(["file", "system", "control", "control_class", "stimulus"])
    archive_file = tempfile.TemporaryFile()
    try:
        with zipfile.ZipFile(archive_file, "w", zipfile.ZIP_STORED) as archive:
            for clip in finished_clips(study):
                name = f"{folder_name(clip.system)}/{clip_name(clip) if clip.control else f'video-{clip.pk}'}.mp4"
                if not clip.video_path().is_file():
                    raise FileNotFoundError(f"the video of {clip.system.name} for "
                                            f"{clip.control.name if clip.control else 'an uploaded video'} is missing.")
                archive.write(clip.video_path(), f"{top}/{name}")
                rows.writerow([name, clip.system.export_name, clip.control.name if clip.control else "",
                               clip.control_class, clip.token])
            archive.writestr(f"{top}/index.csv", index.getvalue())
    except BaseException:
        archive_file.close()
        raise
    archive_file.seek(0)
    return archive_file


__all__ = ["finished_clips", "stimuli_zip"]
