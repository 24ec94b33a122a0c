"""The tests' own servers start though a port they were given is taken before they bind it
(another process can take one between its being found free and its binding): the S3 server,
which leaves nothing behind (neither its folder nor the Unix sockets weed makes beside its
ports), and the PostgreSQL cluster."""

from __future__ import annotations

import socket
import tempfile
from pathlib import Path

import psycopg

from tests import s3_server as s3
from tests import throwaway_postgres as pg


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


def test_the_postgresql_cluster_starts_again_on_another_port_when_its_first_is_taken(monkeypatch):
    taken = socket.socket()
    taken.bind(("127.0.0.1", 0))
    taken.listen()
    handed, free = [], pg.free_port

    def first_port_taken() -> int:
        handed.append(taken.getsockname()[1] if not handed else free())
        return handed[-1]

    monkeypatch.setattr(pg, "free_port", first_port_taken)
    try:
        with pg.throwaway_postgres(durable=False) as (url, _):
            assert len(handed) == 2 and url.endswith(f":{handed[1]}/study")
            with psycopg.connect(url) as connection:
                assert connection.execute("select 1").fetchone() == (1,)
    finally:
        taken.close()
