"""The deployment's proxy (deploy/Caddyfile, Caddy) on free ports of 127.0.0.1, in front of an
app server, for the proxy tests and the crowd benchmark's watching participants.

Where a port found free is taken before Caddy binds it, Caddy stops and is started again on
others. Over HTTPS its certificates come from Caddy's local CA (standing in for Let's Encrypt) and
``tls`` is a client context that trusts that CA alone; with ``https=False`` the same routes are
served over plain HTTP (``STUDY_DOMAIN=http://127.0.0.1:PORT``), and ``tls`` is None.
"""

from __future__ import annotations

import os
import ssl
import subprocess
import time
import urllib.request
from pathlib import Path

from tests.throwaway_postgres import PORT_TAKEN, STARTS, free_port

REPO = Path(__file__).resolve().parents[1]
CADDYFILE = REPO / "deploy" / "Caddyfile"
STATIC = REPO / "studyapp" / "static"
START_TIMEOUT_S = 60
CERTIFICATE_RETRY = '"logger":"tls.obtain","msg":"will retry"'


class PortTaken(Exception):
    """Caddy stopped at its start: one of its ports was taken."""


class Proxy:
    """Caddy with the deployment's Caddyfile in front of ``upstream`` (host:port), sending the
    files under ``media_root`` that the app allows; ``stop()`` ends it."""

    def __init__(self, folder: Path, upstream: str, media_root: Path, https: bool = True) -> None:
        data = folder / "caddy"
        root_certificate = data / "caddy" / "pki" / "authorities" / "local" / "root.crt"
        self._folder = folder
        for start in range(1, STARTS + 1):
            self.port = free_port()
            http_port = self.port if not https else free_port()
            self.url = f"https://localhost:{self.port}" if https else f"http://127.0.0.1:{self.port}"
            self._environment = {
                **os.environ, "STUDY_DOMAIN": "localhost" if https else self.url,
                "STUDY_HTTPS_PORT": str(self.port if https else free_port()), "STUDY_HTTP_PORT": str(http_port),
                "STUDY_LOCAL_CERTS": "local_certs", "STUDY_UPSTREAM": upstream, "MEDIA_ROOT": str(media_root),
                "STATIC_ROOT": str(STATIC), "XDG_DATA_HOME": str(data), "XDG_CONFIG_HOME": str(data),
                "HOME": str(folder)}
            self.log = (folder / "caddy.log").open("w")
            self.process = self._start()
            try:
                self.tls = self._answering(root_certificate if https else None)
                return
            except PortTaken:
                self.log.close()
                if start == STARTS:
                    raise RuntimeError(f"caddy found a port taken {STARTS} times: "
                                       f"{Path(self.log.name).read_text()[-3000:]}") from None

    def _start(self) -> subprocess.Popen:
        return subprocess.Popen(["caddy", "run", "--config", str(CADDYFILE), "--adapter", "caddyfile"],
                                cwd=self._folder, env=self._environment, stdout=self.log, stderr=subprocess.STDOUT)

    def _answering(self, root_certificate: Path | None) -> ssl.SSLContext | None:
        """Once the proxy answers: a context trusting its CA alone (over HTTPS), else None."""
        deadline = time.monotonic() + START_TIMEOUT_S
        restarts = 0
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                said = Path(self.log.name).read_text()
                if PORT_TAKEN in said:
                    raise PortTaken()
                raise RuntimeError(f"caddy exited: {said[-3000:]}")
            if Path(self.log.name).read_text().count(CERTIFICATE_RETRY) > restarts:
                # Caddy 2.6 cleans its storage as it starts, beside obtaining the first certificate,
                # and can delete the new key while it is being written ("because key is empty");
                # it would try again in a minute. Started again, it finds its CA and obtains at once.
                self.stop(close_log=False)
                self.process, restarts = self._start(), restarts + 1
            if root_certificate is None or root_certificate.is_file():
                context = ssl.create_default_context(cafile=str(root_certificate)) if root_certificate else None
                try:
                    urllib.request.urlopen(f"{self.url}/static/studyapp/site.css", context=context, timeout=5).close()
                    return context
                except OSError:  # ssl.SSLError and URLError among them
                    pass
            time.sleep(0.2)
        raise RuntimeError(f"caddy did not answer at {self.url}: {Path(self.log.name).read_text()[-3000:]}")

    def stop(self, close_log: bool = True) -> None:
        self.process.terminate()
        self.process.wait(timeout=20)
        if close_log:
            self.log.close()
