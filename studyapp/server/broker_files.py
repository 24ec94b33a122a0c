"""kombu's filesystem transport (the embedded broker of ``make demo``) with each message
written whole before it is seen.

kombu 5's transport writes a message in place, under the name consumers look for, and
locks it with an advisory lock its own consumer never takes: a worker polling the folder
can move and read a message that is still being written, and fail on half of it (or on
nothing). Here a message is written under a hidden name no queue matches and renamed to
its own once it is whole, which on one file system is atomic.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from time import monotonic

from kombu.exceptions import ChannelError
from kombu.transport import filesystem
from kombu.utils.encoding import str_to_bytes
from kombu.utils.json import dumps


class Channel(filesystem.Channel):
    def _put(self, queue, payload, **kwargs) -> None:
        """Put ``payload`` onto ``queue``, as kombu names it, once it is written whole."""
        name = f"{int(round(monotonic() * 1000))}_{uuid.uuid4()}.{queue}.msg"
        final = os.path.join(self.data_folder_out, name)
        partial = os.path.join(self.data_folder_out, f".{name}.part")
        try:
            with open(partial, "wb") as stream:
                stream.write(str_to_bytes(dumps(payload)))
            os.replace(partial, final)
        except OSError as error:
            with contextlib.suppress(OSError):
                os.unlink(partial)
            raise ChannelError(f"Cannot add file {final!r} to directory") from error


class Transport(filesystem.Transport):
    Channel = Channel


__all__ = ["Channel", "Transport"]
