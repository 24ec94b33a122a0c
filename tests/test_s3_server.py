"""The tests' own S3 server starts though a port it was given is taken before it binds it
(another test's server can take one between its being found free and weed's binding it),
and leaves nothing behind: neither its folder nor the Unix sockets weed makes beside its ports."""

from __future__ import annotations

import socket
import tempfile
from pathlib import Path

from tests import s3_server as s3


def test_the_s3_server_starts_again_on_other_ports_when_one_is_taken_and_leaves_nothing_behind(monkeypatch):
    taken = socket.socket()
    taken.bind(("127.0.0.1", 0))
    taken.listen()
    handed, free = [], s3.free_port

    def master_grpc_port_taken_once() -> int:  # the third port of the first start, its master's gRPC port
        handed.append(taken.getsockname()[1] if len(handed) == 2 else free())
        return handed[-1]

    monkeypatch.setattr(s3, "free_port", master_grpc_port_taken_once)
    sockets_before = set(Path(tempfile.gettempdir()).glob("seaweedfs-*.sock"))
    try:
        with s3.s3_server() as server:
            server.client().put_object(Bucket=server.bucket, Key="clip.mp4", Body=b"motion")
            assert server.keys() == ["clip.mp4"]
            port = server.endpoint_url.rsplit(":", 1)[1]
            folder = next(start.parent for start in Path(tempfile.gettempdir()).glob("throwaway-s3-*/start-*")
                          if port in (start / "log").read_text(errors="replace"))  # this server's
            assert sorted(p.name for p in folder.glob("start-*")) == ["start-1", "start-2"]
            assert "address already in use" in (folder / "start-1" / "log").read_text(errors="replace")
    finally:
        taken.close()
    assert not folder.exists()
    assert set(Path(tempfile.gettempdir()).glob("seaweedfs-*.sock")) <= sockets_before
