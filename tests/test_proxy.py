"""The study served over HTTPS through the proxy of compose.yaml (deploy/Caddyfile, Caddy with
its local CA standing in for Let's Encrypt) in front of the app's live server: a participant
rates clips through it, the clips' bytes sent by the proxy (ranges answered 206 by it) once the
app has allowed them with an empty X-Accel-Redirect answer, and the clips' addresses signed
and expiring. The client trusts the proxy's local CA, and nothing else.
"""

from __future__ import annotations

import http.cookiejar
import os
import re
import signal
import ssl
import subprocess
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import parse_qs, urlencode, urlsplit

import pytest
from django.conf import settings
from django.db import connection
from django.utils.http import http_date

from studyapp.models import Participant, Rating, Study
from studyapp.server.clip_urls import seconds_left, signed_clip_url
from tests.conftest import REPO
from tests.study_fixtures import make_study, render_clip_video
from tests.test_serving_burst import compose_web_command
from tests.test_study_participant import WATCHED, make_shown_long_ago
from tests.throwaway_postgres import free_port

pytestmark = [pytest.mark.django_db(transaction=True), pytest.mark.slow]

CADDYFILE = REPO / "deploy" / "Caddyfile"
STATIC = REPO / "studyapp" / "static"


@pytest.fixture(scope="module")
def clip_video(motion_data, tmp_path_factory) -> Path:
    bvh = motion_data / "data" / "dataset-1_walk_normal_001.bvh"
    return render_clip_video(bvh, tmp_path_factory.mktemp("video") / "clip.mp4", 1.0)


class Proxy:
    """Caddy with the deployment's Caddyfile on free ports, its certificates from its local CA."""

    def __init__(self, folder: Path, upstream: str, media_root: Path) -> None:
        self.port = free_port()
        self.url = f"https://localhost:{self.port}"
        data = folder / "caddy"
        environment = {**os.environ, "STUDY_DOMAIN": "localhost", "STUDY_HTTPS_PORT": str(self.port),
                       "STUDY_HTTP_PORT": str(free_port()), "STUDY_LOCAL_CERTS": "local_certs",
                       "STUDY_UPSTREAM": upstream, "MEDIA_ROOT": str(media_root), "STATIC_ROOT": str(STATIC),
                       "XDG_DATA_HOME": str(data), "XDG_CONFIG_HOME": str(data), "HOME": str(folder)}
        self.log = (folder / "caddy.log").open("w")
        self.process = subprocess.Popen(["caddy", "run", "--config", str(CADDYFILE), "--adapter", "caddyfile"],
                                        cwd=folder, env=environment, stdout=self.log, stderr=subprocess.STDOUT)
        root_certificate = data / "caddy" / "pki" / "authorities" / "local" / "root.crt"
        self.tls = self._trusting(root_certificate)

    def _trusting(self, root_certificate: Path) -> ssl.SSLContext:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise RuntimeError(f"caddy exited: {Path(self.log.name).read_text()[-3000:]}")
            if root_certificate.is_file():
                context = ssl.create_default_context(cafile=str(root_certificate))  # this CA alone
                try:
                    urllib.request.urlopen(f"{self.url}/static/studyapp/site.css", context=context, timeout=5).close()
                    return context
                except OSError:  # ssl.SSLError and URLError among them
                    pass
            time.sleep(0.2)
        raise RuntimeError(f"caddy did not answer over HTTPS: {Path(self.log.name).read_text()[-3000:]}")

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(timeout=20)
        self.log.close()


@pytest.fixture
def media_root(settings, tmp_path) -> Path:
    """The app as compose runs it behind the proxy: media sent by the proxy, cookies for HTTPS."""
    settings.MEDIA_ROOT = tmp_path / "media"
    settings.MEDIA_ACCEL = True
    settings.SESSION_COOKIE_SECURE = settings.CSRF_COOKIE_SECURE = True
    settings.SECURE_PROXY_SSL_HEADER = ("HTTP_X_FORWARDED_PROTO", "https")
    return settings.MEDIA_ROOT


@pytest.fixture
def app_server(media_root, tmp_path) -> Iterator[str]:
    """gunicorn as compose's web service runs it, on this test's database and media folder
    (Django's own live server would send the media files itself); its address."""
    port = free_port()
    environment = {**os.environ, "DATABASE_URL": f"sqlite:///{connection.settings_dict['NAME']}",
                   "SECRET_KEY": settings.SECRET_KEY, "MEDIA_ROOT": str(media_root), "MEDIA_ACCEL": "1",
                   "HTTPS": "1", "ALLOWED_HOSTS": "localhost", "STUDYAPP_VAR_DIR": str(tmp_path / "var")}
    server = subprocess.Popen(compose_web_command(port), cwd=REPO, env=environment, stdout=subprocess.DEVNULL,
                              stderr=(tmp_path / "gunicorn.log").open("w"), start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not _answers(f"http://localhost:{port}/health.json"):
            if server.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"gunicorn did not start: {(tmp_path / 'gunicorn.log').read_text()[-3000:]}")
            time.sleep(0.2)
        yield f"localhost:{port}"
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=20)


def _answers(url: str) -> bool:
    try:
        urllib.request.urlopen(url, timeout=30).close()  # its workers may still be loading the app
        return True
    except OSError:
        return False


@pytest.fixture
def proxy(app_server, media_root, tmp_path) -> Iterator[Proxy]:
    started = Proxy(tmp_path, app_server, media_root)
    yield started
    started.stop()


class Browser:
    """A participant's browser over HTTPS: cookies, the forms' CSRF tokens and the Referer of its page."""

    def __init__(self, proxy: Proxy) -> None:
        self.proxy, self.page_url = proxy, proxy.url
        self.opener = urllib.request.build_opener(urllib.request.HTTPSHandler(context=proxy.tls),
                                                  urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))

    def get(self, path: str, **headers: str):
        request = urllib.request.Request(self.proxy.url + path, headers=headers)
        return self.opener.open(request, timeout=30)

    def page(self, path: str) -> str:
        with self.get(path) as response:
            self.page_url = response.url
            return response.read().decode()

    def post(self, path: str, html: str, **fields) -> str:
        token = re.search(r'name="csrfmiddlewaretoken" value="([^"]+)"', html).group(1)
        request = urllib.request.Request(self.proxy.url + path, data=urlencode({"csrfmiddlewaretoken": token,
                                                                                 **fields}).encode(),
                                         headers={"Referer": self.page_url})
        with self.opener.open(request, timeout=30) as response:
            self.page_url = response.url
            return response.read().decode()


def status_of(browser: Browser, path: str) -> int:
    try:
        with browser.get(path) as response:
            return response.status
    except urllib.error.HTTPError as error:
        return error.code


def test_a_participant_rates_through_the_proxy_with_the_clips_sent_by_it(proxy, app_server, clip_video):
    study = make_study(video=clip_video, clips_per_participant=3, training_clips=1)
    video = clip_video.read_bytes()
    browser = Browser(proxy)
    key = study.key
    html = browser.page(f"/p/{key}/?" + urlencode({"PROLIFIC_PID": "pid-1", "STUDY_ID": "s", "SESSION_ID": "x"}))
    html = browser.post(f"/p/{key}/consent/", html, agree="yes")
    html = browser.post(f"/p/{key}/instructions/", html)
    participant = Participant.objects.get(study=study, platform_id="pid-1")
    for index in range(len(participant.training)):
        html = browser.post(f"/p/{key}/practice/", html, index=index, value=3)
    seen = []
    while match := re.search(r'name="assignment" value="([0-9a-f]+)"', html):
        clip = re.search(r'<video id="clip" src="([^"]+)"', html).group(1).replace("&amp;", "&")
        seen.append(clip)
        with browser.get(clip, Range="bytes=100-199") as part:
            assert part.status == 206 and part.headers["Content-Range"] == f"bytes 100-199/{len(video)}"
            assert part.read() == video[100:200]
        with browser.get(clip) as whole:
            assert whole.read() == video
            # The proxy's answer, with nothing that dates the clip's rendering, kept while its address works.
            assert whole.headers["Server"] == "Caddy" and whole.headers["Cache-Control"].startswith("private, max-age=")
            kept = int(whole.headers["Cache-Control"].rpartition("=")[2])
            assert abs(kept - seconds_left(query_of(clip))) <= 2 and kept >= settings.CLIP_URL_LIFETIME_S - 60
            assert whole.headers["Content-Type"] == "video/mp4"
            assert "Last-Modified" not in whole.headers and "ETag" not in whole.headers
            assert "X-Accel-Redirect" not in whole.headers
        make_shown_long_ago(participant)  # as if the clip had played to its end
        html = browser.post(f"/p/{key}/rate/", html, assignment=match.group(1), value=4, **WATCHED)

    assert "C0MPL3TE" in html
    assert Rating.objects.filter(assignment__participant=participant).count() == 3 == len(seen)
    # The app itself sent no byte of a clip: its answer to the same address is empty, naming the file.
    with urllib.request.urlopen(f"http://{app_server}{seen[0]}", timeout=30) as direct:
        token = re.search(r"/media/stimuli/([0-9a-f]+)\.mp4\?", seen[0]).group(1)
        assert direct.read() == b"" and direct.headers["X-Accel-Redirect"] == f"/_accel/media/stimuli/{token}.mp4"


def query_of(address: str) -> dict[str, str]:
    return {key: values[0] for key, values in parse_qs(urlsplit(address).query).items()}


def test_no_conditional_request_tells_when_a_clip_was_rendered(proxy, clip_video):
    """A file's time is in the proxy's 304 and 412 answers as surely as in a Last-Modified
    header: asked whether a clip changed since a moment just after and just before it was
    written, the proxy answers alike, and a range request with a validator is a range still."""
    study = make_study(video=clip_video, controls=1)
    stimulus = study.stimuli.first()
    written = (settings.MEDIA_ROOT / stimulus.relative_path).stat().st_mtime
    browser = Browser(proxy)
    after, before = http_date(written + 2), http_date(written - 2)
    answers = []
    for headers in ({"If-Modified-Since": after}, {"If-Modified-Since": before}, {"If-Unmodified-Since": before},
                    {"If-None-Match": "*"}, {"If-Match": '"x"'}, {"Range": "bytes=0-9", "If-Range": before}):
        try:
            with browser.get(stimulus.video_url, **headers) as answer:
                answers.append((answer.status, len(answer.read())))
        except urllib.error.HTTPError as refused:  # 304 Not Modified, 412 Precondition Failed
            answers.append((refused.code, 0))
            answer = refused
        assert "Last-Modified" not in answer.headers and "ETag" not in answer.headers, headers
    size = clip_video.stat().st_size
    assert answers == [(200, size)] * 5 + [(206, 10)]


def test_a_clip_address_unsigned_altered_expired_or_internal_is_refused_by_the_app(proxy, clip_video):
    study = make_study(video=clip_video, controls=1)
    stimulus = study.stimuli.first()
    browser = Browser(proxy)
    signed = stimulus.video_url
    assert "?until=" in signed and "&sig=" in signed and status_of(browser, signed) == 200
    other = study.stimuli.exclude(pk=stimulus.pk).first()

    assert status_of(browser, f"/media/{stimulus.relative_path}") == 404  # the plain address
    assert status_of(browser, signed.replace(stimulus.token, other.token)) == 404  # another clip's signature
    assert status_of(browser, signed[:-1] + ("0" if signed[-1] != "0" else "1")) == 404
    assert status_of(browser, signed_clip_url(stimulus.relative_path, now=time.time() - 2 * 3600)) == 404
    assert status_of(browser, f"/_accel/media/{stimulus.relative_path}") == 404  # only the app's answer leads there


def test_static_files_come_from_the_proxy_with_caching_headers(proxy):
    browser = Browser(proxy)
    with browser.get("/static/studyapp/site.css") as response:
        assert response.read() == (STATIC / "studyapp" / "site.css").read_bytes()
        assert response.headers["Cache-Control"] == "public, max-age=3600"
        assert response.headers["Server"] == "Caddy"


def test_the_researchers_files_stay_behind_their_login_through_the_proxy(proxy):
    browser = Browser(proxy)
    for path in ("/media/gallery/anything.mp4", "/media/reports/" + "0" * 64 + "/ratings.csv"):
        with browser.get(path) as response:  # redirected to the login page, never the file
            assert "/login/" in response.url
    assert status_of(browser, "/media/checkpoints/x.safetensors") == 404


def test_the_caddyfile_is_valid_with_composes_settings_for_a_real_domain(tmp_path):
    from tests.test_compose import load_compose

    given = load_compose()["services"]["proxy"]["environment"]
    defaults = {name: re.sub(r"^\$\{[A-Z_]+:-(.*)\}$", r"\1", str(value)) for name, value in given.items()}
    environment = {**os.environ, **defaults, "STUDY_DOMAIN": "study.example.org", "XDG_DATA_HOME": str(tmp_path),
                   "XDG_CONFIG_HOME": str(tmp_path), "HOME": str(tmp_path)}
    checked = subprocess.run(["caddy", "validate", "--config", str(CADDYFILE), "--adapter", "caddyfile"],
                             cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=60)

    assert checked.returncode == 0, checked.stderr[-3000:]
    assert "Valid configuration" in checked.stdout + checked.stderr
