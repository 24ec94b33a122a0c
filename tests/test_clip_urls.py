"""Behind the proxy (MEDIA_ACCEL) the app decides who may see a media file and answers with an
empty X-Accel-Redirect naming it, and a clip's address is signed and expires; without the
proxy the plain addresses and the app's own range answers stay (tests/test_media_range.py)."""

import time
from pathlib import Path
from urllib.parse import parse_qsl, urlparse

import pytest

from studyapp.server.clip_urls import is_signed_and_current, signed_clip_url

CLIP = "stimuli/0123456789abcdef0123456789abcdef.mp4"


@pytest.fixture
def behind_the_proxy(settings, tmp_path: Path) -> Path:
    settings.MEDIA_ROOT = tmp_path / "media"
    settings.MEDIA_ACCEL = True
    (settings.MEDIA_ROOT / "stimuli").mkdir(parents=True)
    (settings.MEDIA_ROOT / CLIP).write_bytes(b"a rendered clip")
    (settings.MEDIA_ROOT / "stimuli" / ".0123.mp4.part").write_bytes(b"half a clip")
    return settings.MEDIA_ROOT


def query_of(url: str) -> dict[str, str]:
    return dict(parse_qsl(urlparse(url).query))


def test_a_signed_clip_is_allowed_with_an_empty_answer_that_names_it_for_the_proxy(client, behind_the_proxy):
    response = client.get(signed_clip_url(CLIP))

    assert response.status_code == 200 and response.content == b""
    assert response["X-Accel-Redirect"] == f"/_accel/media/{CLIP}"


def test_behind_the_proxy_the_plain_clip_address_and_hidden_or_outside_files_are_refused(client, behind_the_proxy):
    assert client.get(f"/media/{CLIP}").status_code == 404
    assert client.get(signed_clip_url("stimuli/.0123.mp4.part")).status_code == 404
    assert client.get(signed_clip_url("stimuli/../../etc/passwd")).status_code == 404
    assert client.get("/media/reports/" + "0" * 64 + "/ratings.csv").status_code == 302  # to the login page


def test_a_clip_address_works_for_its_lifetime_and_an_eighth_at_most(settings):
    now = 1_800_000_000.0
    lifetime = settings.CLIP_URL_LIFETIME_S
    query = query_of(signed_clip_url(CLIP, now=now))

    until = int(query["until"])
    assert now + lifetime <= until <= now + lifetime * 9 / 8
    assert is_signed_and_current(CLIP, query, now=until - 1)
    assert not is_signed_and_current(CLIP, query, now=until + 1)
    assert not is_signed_and_current(CLIP.replace("0123", "3210"), query, now=now)
    assert not is_signed_and_current(CLIP, {**query, "until": str(until + 1)}, now=now)
    assert not is_signed_and_current(CLIP, {"until": "9" * 40, "sig": query["sig"]}, now=now)


def test_the_pages_of_a_few_minutes_name_a_clip_by_one_address_so_a_fetched_ahead_clip_is_reused(settings):
    start = time.time()
    addresses = {signed_clip_url(CLIP, now=start + seconds) for seconds in range(0, 60, 5)}
    assert len(addresses) <= 2  # one, unless a rounding step falls within the minute


def test_without_the_proxy_the_clip_addresses_are_the_plain_ones(settings):
    from studyapp.models import Stimulus

    settings.MEDIA_ACCEL = False
    assert Stimulus(token="ab" * 16).video_url == f"/media/stimuli/{'ab' * 16}.mp4"
    settings.MEDIA_ACCEL = True
    assert Stimulus(token="ab" * 16).video_url.startswith(f"/media/stimuli/{'ab' * 16}.mp4?until=")


def through_the_gate(url: str, method: str = "GET") -> tuple[str, dict[str, str], bool]:
    """The status and headers the WSGI application gives ``url``, and whether Django answered it."""
    from studyapp.server.clip_urls import answering_signed_clips

    django_asked, answered = [], {}
    path, _, query = url.partition("?")

    def django(environ, start_response):
        django_asked.append(environ["PATH_INFO"])
        start_response("404 Not Found", [("Content-Type", "text/html")])
        return [b"Django's answer"]

    def start_response(status, headers):
        answered.update(status=status, headers=dict(headers))

    body = b"".join(answering_signed_clips(django)({"REQUEST_METHOD": method, "PATH_INFO": path, "QUERY_STRING": query},
                                                    start_response))
    assert body == (b"Django's answer" if django_asked else b"")
    return answered["status"], answered["headers"], bool(django_asked)


def test_a_signed_clip_is_answered_ahead_of_django_as_the_media_view_answers_it(client, behind_the_proxy):
    url = signed_clip_url(CLIP)
    status, headers, django_asked = through_the_gate(url)
    view = client.get(url)

    assert status == "200 OK" and not django_asked
    assert headers["X-Accel-Redirect"] == view["X-Accel-Redirect"] == f"/_accel/media/{CLIP}"
    assert headers["Cache-Control"] == view["Cache-Control"] and headers["Content-Length"] == "0"
    assert through_the_gate(url, "HEAD")[0] == "200 OK"


def test_every_other_clip_request_goes_on_to_django_which_refuses_it(behind_the_proxy, settings):
    query = query_of(signed_clip_url(CLIP))
    expired = signed_clip_url(CLIP, now=time.time() - settings.CLIP_URL_LIFETIME_S * 2)
    for url in (f"/media/{CLIP}", f"/media/{CLIP}?until={query['until']}&sig={'0' * 32}", expired,
                signed_clip_url("stimuli/.0123.mp4.part"), signed_clip_url("stimuli/absent.mp4"),
                signed_clip_url("stimuli/../../etc/passwd"), "/media/reports/x.csv", "/p/some-study/"):
        assert through_the_gate(url)[2], url
    assert through_the_gate(signed_clip_url(CLIP), "POST")[2]
    settings.MEDIA_ACCEL = False  # no proxy in front: the app sends the clip itself
    assert through_the_gate(signed_clip_url(CLIP))[2]
