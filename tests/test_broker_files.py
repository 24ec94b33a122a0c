"""The embedded broker (kombu's filesystem transport, ``studyapp.server.broker_files``): a
worker polling the queue folder while a message is being written does not read it before
it is whole. The window is held open by pausing the producer between creating the message's
file and writing its bytes, where the worker's poll comes in."""

from __future__ import annotations

import json
from queue import Empty

from kombu import Connection
from kombu.transport import filesystem

from studyapp.server import broker_files
from studyapp.server.embedded import FILESYSTEM_BROKER_URL, filesystem_broker_options

MESSAGE = {"body": "a task's message", "properties": {"delivery_tag": "1"}}


def polled_while_written(module, transport, tmp_path, monkeypatch) -> list:
    """What a worker's poll finds while ``transport`` writes MESSAGE (the module's ``open``
    pausing before the bytes go in), then what it finds once the message is written."""
    options = filesystem_broker_options(tmp_path)
    worker = Connection(FILESYSTEM_BROKER_URL, transport=transport, transport_options=options).channel()
    found = []

    def poll():
        try:
            found.append(worker._get("celery"))
        except Empty:
            found.append("nothing")
        except ValueError as error:  # the message half there
            found.append(f"unreadable: {error}")

    class Paused:
        def __init__(self, stream):
            self.stream = stream

        def write(self, data):
            poll()
            return self.stream.write(data)

        def __getattr__(self, name):
            return getattr(self.stream, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.stream.close()

    monkeypatch.setattr(module, "open", lambda *args, **kwargs: Paused(open(*args, **kwargs)), raising=False)
    producer = Connection(FILESYSTEM_BROKER_URL, transport=transport, transport_options=options).channel()
    producer._put("celery", MESSAGE)
    monkeypatch.undo()
    poll()
    return found


def test_kombus_own_transport_lets_a_worker_read_a_message_still_being_written(tmp_path, monkeypatch):
    found = polled_while_written(filesystem, filesystem.Transport, tmp_path, monkeypatch)
    assert found[0].startswith("unreadable") and found[1] == "nothing"  # read empty, and so lost


def test_a_message_is_seen_only_once_it_is_whole(tmp_path, monkeypatch):
    found = polled_while_written(broker_files, broker_files.Transport, tmp_path, monkeypatch)
    assert found == ["nothing", json.loads(json.dumps(MESSAGE))]
    assert sorted(path.name for path in (tmp_path / "broker" / "queue").iterdir()) == []


def test_the_app_uses_this_transport_for_the_filesystem_broker():
    from studyapp.server.celery import app

    assert app.connection_for_write(FILESYSTEM_BROKER_URL).get_transport_cls() is broker_files.Transport
