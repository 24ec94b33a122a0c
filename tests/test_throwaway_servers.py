"""The tests' own servers start though a port they were given is taken before they bind it
(another process can take one between its being found free and its binding): the S3 server,
which leaves nothing behind (neither its folder nor the Unix sockets weed makes beside its
ports), the PostgreSQL cluster and the proxy."""

from __future__ import annotations

import socket
import tempfile
import urllib.request
from pathlib import Path

import psycopg

from tests import caddy_proxy
from tests import s3_server as s3
from tests import throwaway_postgres as pg


def first_port_taken(module, taken: socket.socket, nth: int = 0):
    """A stand-in for ``module.free_port`` that hands out ``taken``'s port at its ``nth`` call,
    and free ones otherwise; the list of the ports it handed out."""
    handed, free = [], module.free_port

    def free_port() -> int:
        handed.append(taken.getsockname()[1] if len(handed) == nth else free())
        return handed[-1]

    return free_port, handed


def taken_port() -> socket.socket:
    taken = socket.socket()
    taken.bind(("127.0.0.1", 0))
    taken.listen()
    return taken


def test_the_s3_server_starts_again_on_other_ports_when_one_is_taken_and_leaves_nothing_behind(monkeypatch):
    taken = taken_port()
    free_port, _ = first_port_taken(s3, taken, nth=2)  # the first start's third port, its master's gRPC port
    monkeypatch.setattr(s3, "free_port", free_port)
    sockets_before = set(Path(tempfile.gettempdir()).glob("seaweedfs-*.sock"))
    try:
        with s3.s3_server() as server:
            server.client().put_object(Bucket=server.bucket, Key="clip.mp4", Body=b"motion")
            assert server.keys() == ["clip.mp4"]
            arguments = Path(f"/proc/{server.pid}/cmdline").read_bytes().decode().split("\0")
            data = Path(next(argument for argument in arguments if argument.startswith("-dir="))[len("-dir="):])
            folder = data.parents[1]  # its folder/start-N/data
            assert sorted(p.name for p in folder.glob("start-*")) == ["start-1", "start-2"]
            assert "address already in use" in (folder / "start-1" / "log").read_text(errors="replace")
    finally:
        taken.close()
    assert not folder.exists()
    assert set(Path(tempfile.gettempdir()).glob("seaweedfs-*.sock")) <= sockets_before


def test_the_postgresql_cluster_starts_again_on_another_port_when_its_first_is_taken(monkeypatch):
    taken = taken_port()
    free_port, handed = first_port_taken(pg, taken)
    monkeypatch.setattr(pg, "free_port", free_port)
    try:
        with pg.throwaway_postgres(durable=False) as (url, _):
            assert len(handed) == 2 and url.endswith(f":{handed[1]}/study")
            with psycopg.connect(url) as connection:
                assert connection.execute("select 1").fetchone() == (1,)
    finally:
        taken.close()


def test_the_proxy_starts_again_on_other_ports_when_its_first_is_taken(monkeypatch, tmp_path):
    taken = taken_port()
    free_port, handed = first_port_taken(caddy_proxy, taken)
    monkeypatch.setattr(caddy_proxy, "free_port", free_port)
    try:
        proxy = caddy_proxy.Proxy(tmp_path, "127.0.0.1:9", tmp_path, https=False)  # its static files need no app
        try:
            assert proxy.port != handed[0] and proxy.port in handed[1:]  # the first start, on the taken port, stopped
            with urllib.request.urlopen(f"{proxy.url}/static/studyapp/site.css", timeout=5) as response:
                assert response.status == 200
        finally:
            proxy.stop()
    finally:
        taken.close()
