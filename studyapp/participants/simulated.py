"""Simulated participants: take a live study from its entry link to the completion page over HTTP.

A dry run before a study goes to the crowd, the concurrency test and the ratings
benchmark all use it. Each participant is an independent cookie-carrying client that
reads the page it is on, as a browser would, and answers it: the device check (with a
screen as large as the study asks), consent, screening questions (a random choice, which
may screen it out; a number within the question's range; a line of text), instructions,
practice clips, then a rating per clip, or an answer per side-by-side, pairwise or
appropriateness page (claiming to have watched every clip to its end, and so answering no
sooner than the longest clip on the page lasts; an instructed check answered as it asks),
and the closing questions. Pages of clips are answered as their script answers
them, asking for the next page in the answer's response (``path.NEXT_PAGE_HEADER``); a
server that answers with a redirect instead (the form without the script, or an older
version of the app) has its redirect followed.

Each participant ends one of four ways, which the summary counts: finished, screened out,
refused because the study was full, or failed, with the reason (the page's own message of
a refused form or request, or where the study ended otherwise, as on failed instructed
checks).

    python -m studyapp.participants.simulated http://127.0.0.1:8000/p/KEY/ -n 20

Only the Python standard library is used, so it runs anywhere the app does.
"""

from __future__ import annotations

import argparse
import html
import http.cookiejar
import math
import random
import re
import statistics
import sys
import time
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

_FORM = re.compile(r'<form method="post" action="([^"]+)"[^>]*>(.*?)</form>', re.S)
_HIDDEN = re.compile(r'<input type="hidden" name="([^"]+)"(?: value="([^"]*)")?>')
_POINT = re.compile(r'<button type="submit" name="value" value="(-?\d+)"(?: disabled)?>')
# Side-by-side and pairwise pages: a slider per clip, or the answer buttons and strengths.
_SLIDER = re.compile(r'<input type="range" form="page-form" id="[^"]+" name="(value-\d+)"[^>]*? min="(-?\d+)" max="(-?\d+)"')
_ANSWER = re.compile(r'<button type="submit" name="answer" value="(\w+)"')
_STRENGTH = re.compile(r'<button type="submit" name="strength" value="(\d+)"')
_PLAY = re.compile(r'data-play="(\d+)"')
_RATING_STEP = "/rate/"
_CLIP_STEPS = ("/practice/", _RATING_STEP)  # the forms that the clip pages' script sends
# path.NEXT_PAGE_HEADER (not imported: this module runs with the standard library alone).
_IN_PLACE = {"Studyapp-Next-Page": "in-place"}
_CLIP_SECONDS = re.compile(r'<video [^>]*data-seconds="([0-9.]+)"')
_DEVICE_STEP = "/device/"
_DEVICE_NEED = re.compile(r"const minWidth = (\d+), minHeight = (\d+);")
_SCREEN = (1280, 800)  # a laptop's viewport, or the study's least screen where that is larger
_QUESTIONS = 'class="questions"'
_CHOICE = re.compile(r'<input type="radio" name="([^"]+)" value="([^"]*)"')
_NUMBER = re.compile(r'<input type="number" step="([^"]+)" min="([^"]+)" max="([^"]+)" name="([^"]+)"')
_TEXT = re.compile(r'<textarea name="([^"]+)"')
# The answer an instructed check asks for, per clip, in any language (the page's data-expected):
# a point (single), the side to choose (pairwise), or "max" on the slider to move to the far right.
_INSTRUCTION = re.compile(r'<p class="instruction" data-expected="([^"]*)">')
_HEADING = re.compile(r"<h1>(.*?)</h1>", re.S)
_NOTICE = re.compile(r'<p class="notice[^"]*"[^>]*>(.*?)</p>', re.S)
# How a participant's study ended, by its last page's heading (data-ending, in any language).
FINISHED, SCREENED_OUT, FULL, FAILED = "finished", "screened out", "refused because the study was full", "failed"
_ENDINGS = {"finished": FINISHED, "screened-out": SCREENED_OUT, "full": FULL}
_ENDING = re.compile(r'<h1 data-ending="([\w-]+)">')


def longest_clip_s(page: str) -> float:
    """How long the longest clip on a page plays: the least time after the page was shown
    before the server takes an answer as given after the end of every clip on it."""
    return max((float(seconds) for seconds in _CLIP_SECONDS.findall(page)), default=0.0)


@dataclass
class Outcome:
    """What one simulated participant did and how long each rating submission took."""

    platform_id: str
    finished: bool = False
    ratings: int = 0  # accepted by the server (answered with the next page, or the redirect to it)
    rating_latencies_s: list[float] = field(default_factory=list)
    final_page: str = ""
    error: str = ""  # why it failed: the server's message, or where the study ended otherwise

    @property
    def ending(self) -> str:
        """FINISHED, SCREENED_OUT, FULL or FAILED."""
        if self.error:
            return FAILED
        found = _ENDING.search(self.final_page)
        return _ENDINGS.get(found.group(1), FAILED) if found else FAILED


def page_message(body: str) -> str:
    """A page's heading and its notice (the app's message pages: a refused form, a full study), in plain words."""
    parts = [m.group(1) for m in (_HEADING.search(body), _NOTICE.search(body)) if m]
    return ": ".join(html.unescape(re.sub(r"<[^>]+>", "", part)).strip() for part in parts)


class _KeepRedirects(urllib.request.HTTPRedirectHandler):
    """Hand a redirect back as an HTTPError instead of following it, so that an accepted
    rating (the redirect) is counted even when the next page then fails."""

    def redirect_request(self, *args, **kwargs) -> None:
        return None


class SimulatedParticipant:
    """One participant with their own cookies; ``run()`` goes through the whole study."""

    def __init__(self, entry_url: str, platform_id: str, id_parameter: str = "PROLIFIC_PID",
                 rng: random.Random | None = None, timeout_s: float = 60.0, watch_s: float = 0.0) -> None:
        separator = "&" if "?" in entry_url else "?"
        self.entry_url = f"{entry_url}{separator}{urllib.parse.urlencode({id_parameter: platform_id})}"
        self.outcome = Outcome(platform_id)
        self.rng = rng or random.Random(platform_id)
        self.timeout_s = timeout_s
        self.watch_s = watch_s  # least time spent on each rating page before answering, as a person watches it
        cookies = urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar())
        self.opener = urllib.request.build_opener(cookies)
        self.rating_opener = urllib.request.build_opener(cookies, _KeepRedirects)

    def _open(self, url: str, data: dict | None = None, headers: dict | None = None) -> tuple[str, str]:
        """(final URL, body) after redirects; a 4xx/5xx raises urllib.error.HTTPError."""
        request = urllib.request.Request(url, urllib.parse.urlencode(data).encode() if data is not None else None,
                                         headers=headers or {})
        with self.opener.open(request, timeout=self.timeout_s) as response:
            return response.geturl(), response.read().decode()

    def _answer(self, page_url: str, body: str) -> tuple[str, str] | None:
        """Submit the page's form; None when the page has no form (the end, or a message)."""
        match = _FORM.search(body)
        if not match:
            return None
        action, form = html.unescape(match.group(1)), match.group(2)
        data = {name: html.unescape(value or "") for name, value in _HIDDEN.findall(form)}
        points = [int(point) for point in _POINT.findall(form)]
        url = urllib.parse.urljoin(page_url, action)
        sliders, answers = _SLIDER.findall(body), _ANSWER.findall(form)
        if action.endswith("/consent/"):
            data["agree"] = "yes"
        elif action.endswith(_DEVICE_STEP):
            need = _DEVICE_NEED.search(body)
            width, height = (max(int(n), least) for n, least in zip(need.groups() if need else (0, 0), _SCREEN))
            data.update(width=str(width), height=str(height))
        elif _QUESTIONS in match.group(0):
            data.update(self._questions_answer(form))
        elif points or sliders or answers:  # a rating page: every clip on it played to its end first
            self._watch(body)
            found = _INSTRUCTION.search(body)
            asked = html.unescape(found.group(1)).split(",") if found else []
            if points:
                value = asked[0] if asked else str(self.rng.choice(points))
                data.update(value=value, started_s="0.05", ended_s="0.5", answered_s="0.6", played_until_s="0.45")
            else:
                data.update(self._page_answer(body, sliders, answers, _STRENGTH.findall(form)))
                if asked and answers:
                    data["answer"] = asked[0]
                    if strengths := _STRENGTH.findall(form):  # a choice asked with its strength
                        data["strength"] = self.rng.choice(strengths)
                elif "max" in asked:
                    name, _, high = sliders[asked.index("max")]
                    data[name] = high
        if action.endswith(_RATING_STEP):
            start = time.perf_counter()
            next_url, next_body = self._rate(url, data)
            self.outcome.ratings += 1
            result = (next_url, next_body) if next_body is not None else self._open(next_url)
            self.outcome.rating_latencies_s.append(time.perf_counter() - start)
            return result
        return self._open(url, data, _IN_PLACE if action.endswith(_CLIP_STEPS) else None)

    def _watch(self, body: str) -> None:
        """Stay on a rating page as a person watching its clips does: its longest clip, at least ``watch_s``."""
        time.sleep(max(self.watch_s, longest_clip_s(body)))

    def _page_answer(self, body: str, sliders: list[tuple[str, str, str]], answers: list[str],
                     strengths: list[str]) -> dict:
        """A random answer to a side-by-side or pairwise page, every clip claimed watched to its end."""
        data = {name: str(self.rng.randint(int(low), int(high))) for name, low, high in sliders}
        data.update({name.replace("value-", "moved-"): "1" for name, _, _ in sliders})  # each slider moved
        if answers:
            data["answer"] = self.rng.choice(answers)
            if strengths and data["answer"] != "none":
                data["strength"] = self.rng.choice(strengths)
        for slot in _PLAY.findall(body):
            data.update({f"started_s-{slot}": "0.05", f"ended_s-{slot}": "0.5", f"answered_s-{slot}": "0.6",
                         f"played_until_s-{slot}": "0.45"})
        return data

    def _questions_answer(self, form: str) -> dict:
        """An answer to every question of a questionnaire: a random choice, a number within
        the question's range (whole where it asks for one), a line of text."""
        data: dict[str, str] = {}
        for name, choice in _CHOICE.findall(form):
            data.setdefault(name, [])
            data[name].append(html.unescape(choice))
        data = {name: self.rng.choice(choices) for name, choices in data.items()}
        for step, low, high, name in _NUMBER.findall(form):
            value = self.rng.uniform(float(low), float(high))
            data[name] = str(min(max(round(value), math.ceil(float(low))), math.floor(float(high)))
                             if step == "1" else round(value, 2))
        data.update({name: "An answer from the dry run." for name in _TEXT.findall(form)})
        return data

    def _rate(self, url: str, data: dict) -> tuple[str, str | None]:
        """POST a rating as the page's script does, once the server has stored it: (URL,
        body) of the next page where the response is that page, else (the URL the server
        redirects to, None)."""
        request = urllib.request.Request(url, urllib.parse.urlencode(data).encode(), headers=_IN_PLACE)
        try:
            with self.rating_opener.open(request, timeout=self.timeout_s) as response:
                return url, response.read().decode()
        except urllib.error.HTTPError as answer:
            if answer.code in (302, 303):
                return urllib.parse.urljoin(url, answer.headers["Location"]), None
            raise

    def run(self, max_pages: int = 500) -> Outcome:
        try:
            url, body = self._open(self.entry_url)
            for _ in range(max_pages):
                answered = self._answer(url, body)
                if answered is None:
                    break
                url, body = answered
            self.outcome.final_page = body
            self.outcome.finished = self.outcome.ending == FINISHED
            if self.outcome.ending == FAILED:
                self.outcome.error = f"the study ended at {urllib.parse.urlsplit(url).path}: {page_message(body)}"
        except urllib.error.HTTPError as error:  # the app's message page says why it refused
            where = urllib.parse.urlsplit(error.url or "").path
            said = page_message(error.read().decode(errors="replace"))
            self.outcome.error = f"HTTP {error.code} on {where}" + (f": {said}" if said else f": {error.reason}")
        except (urllib.error.URLError, TimeoutError, ConnectionError) as error:
            self.outcome.error = f"{type(error).__name__}: {error}"
        return self.outcome


def run_participants(entry_url: str, count: int, concurrency: int | None = None,
                     id_parameter: str = "PROLIFIC_PID", prefix: str = "sim", watch_s: float = 0.0,
                     participant: Callable[..., SimulatedParticipant] | None = None) -> list[Outcome]:
    """``count`` participants, ``concurrency`` at a time (default: all at once), each
    spending at least ``watch_s`` on every rating page before answering; ``participant``
    makes each (default: ``SimulatedParticipant``, or a kind of it that does more)."""
    participant = participant or SimulatedParticipant
    participants = [participant(entry_url, f"{prefix}-{i:05d}", id_parameter, watch_s=watch_s)
                    for i in range(count)]
    with ThreadPoolExecutor(max_workers=concurrency or count) as pool:
        return list(pool.map(SimulatedParticipant.run, participants))


def percentile(values: list[float], q: float) -> float:
    """The q-quantile (0..1) by linear interpolation between order statistics."""
    ordered = sorted(values)
    position = q * (len(ordered) - 1)
    low = int(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("entry_url", help="the study's entry link without the platform's id, e.g. http://host/p/KEY/")
    parser.add_argument("-n", "--participants", type=int, default=10, help="how many (default %(default)s)")
    parser.add_argument("--concurrency", type=int, help="how many at a time (default: all)")
    parser.add_argument("--id-parameter", default="PROLIFIC_PID",
                        help="query parameter carrying the id: PROLIFIC_PID, workerId or pid (default %(default)s)")
    parser.add_argument("--prefix", default="sim", help="platform ids are PREFIX-00000, ... (default %(default)s)")
    parser.add_argument("--watch", type=float, default=0.0,
                        help="least seconds on each rating page before answering; a page is answered no sooner "
                             "than its longest clip lasts either way (default %(default)s)")
    args = parser.parse_args(argv)
    if args.participants < 1 or (args.concurrency is not None and args.concurrency < 1):
        parser.error("--participants and --concurrency must be at least 1")
    if not 0.0 <= args.watch < float("inf"):  # also refuses nan
        parser.error(f"--watch must be a finite number of seconds, 0 or more, not {args.watch}")
    start = time.perf_counter()
    outcomes = run_participants(args.entry_url, args.participants, args.concurrency, args.id_parameter, args.prefix,
                                args.watch)
    seconds = time.perf_counter() - start
    latencies = [s for o in outcomes for s in o.rating_latencies_s]
    print(summary(outcomes) + f"; {len(latencies)} ratings in {seconds:.1f} s")
    if latencies:
        print(f"rating submission: median {statistics.median(latencies) * 1000:.0f} ms, "
              f"p95 {percentile(latencies, 0.95) * 1000:.0f} ms")
    for reason, count in Counter(o.error for o in outcomes if o.error).most_common():
        print(f"failed ({count}): {reason}", file=sys.stderr)
    return 0 if all(not o.error for o in outcomes) else 1


def summary(outcomes: list[Outcome]) -> str:
    """How the participants ended: finished, screened out, refused because full, failed."""
    counts = Counter(o.ending for o in outcomes)
    return (f"{len(outcomes)} participants: " + ", ".join(f"{counts[ending]} {ending}"
                                                          for ending in (FINISHED, SCREENED_OUT, FULL, FAILED)))


if __name__ == "__main__":
    raise SystemExit(main())
