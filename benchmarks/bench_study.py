"""Benchmark: one rating step's server time, crowds of simultaneous participants, and the
wait between an answer and the next clip in a real browser.

A rating step is the answer as the clip page's script sends it (``path.NEXT_PAGE_HEADER``)
until the next page is in hand: one request whose response is the next page; for a
reference code from before the one-request step, the POST and the page it redirects to.

*Server time*: one participant at a time goes through a 20-clip study inside the
server's own process (Django's test client: the whole middleware stack, CSRF checked,
no network), and each rating step is timed, with its queries counted; on the embedded
default (SQLite) and on PostgreSQL. With ``--reference-code DIR`` (another checkout of the project, such as
the code before a change: ``git archive REV | tar -x -C DIR``) that code's rating step is
timed in the same run, round by round alternating with this one's, so that a shared
machine's load reaches both. Forms are posted urlencoded, as browsers send them.

*Crowds*: simulated participants (studyapp.participants.simulated: real HTTP, cookies,
CSRF) take the study at once, in processes of their own (threads within them), against
the embedded default of ``make demo`` (``manage.py serve``, SQLite) and the
production shape (gunicorn with the threaded workers of compose.yaml, PostgreSQL on
127.0.0.1), under two loads: *saturation* (every participant answers the moment a page
arrives: the most ratings per second the setup takes) and *watching* (each spends
WATCH_S on a clip's page first, as a person watching a clip does); then 500 and 1,000
watching participants on the production shape. Reported: rating submissions per second
over the whole run (every page of every participant is fetched too), the median and
95th-percentile latency of a rating step, the share of the machine's CPU time that the
participants, the server and PostgreSQL used (they share its cores, so the latencies
are an upper bound for a server with a machine of its own), and a check that the
database holds exactly the ratings the server accepted (answered with its redirect; a
rating whose next page then fails is still counted). Latency targets apply to the
watching load: at saturation latency is queueing by construction.

*Targets* (``--only targets``): the crowds that the targets are set for, each measured
with this code and, with ``--reference-code``, the reference code in the same run, one
after the other: gunicorn + PostgreSQL at saturation (ratings/s, target >= 200) and with
1,000 watching (p95 < 500 ms), ``manage.py serve`` + SQLite with 200 watching (p95 <
250 ms), and *answer to play*: a participant in headless Chromium (Debian's chromium,
driven by Playwright) rates 4-s clips of real motion on ``manage.py serve`` + SQLite, and
the time from each answer (the form's submit event) to the next clip's "playing" event is
taken from the page's own clock (median target < 300 ms). The clip is rendered from the
first BVH file under ``$MOTION_DATA`` (default ../shared/data/bandai-namco-1).

*Floor* (``--only floor``, and with the targets): the production shape serving the least
a rating request must do (``benchmarks.stack_floor``: a CSRF-checked form, a signed
cookie, one transaction of a read and two writes, a 1 kB page) to ``FLOOR_CLIENTS``
clients asking as fast as they can for ``FLOOR_S``: the requests per second and CPU per
request that no rating step of this stack can beat on the machine, against which the
saturation's ratings per second and CPU per rating are read.

*Clips*: ``bench_study_clips.py``, this benchmark's crowds downloading every clip.

    python benchmarks/bench_study.py [--participants 100] [--crowds 500,1000] [--json]   # everything
    python benchmarks/bench_study.py --only server-time --reference-code /tmp/before     # the rating step
    python benchmarks/bench_study.py --only crowd            # 100 at saturation and watching, both setups
    python benchmarks/bench_study.py --only large --crowds 500   # one large crowd at a time
    python benchmarks/bench_study.py --only targets --reference-code /tmp/before   # the four targets, both codes
    python benchmarks/bench_study.py --only floor            # the least a rating request costs here

Needs PostgreSQL's server programs (Debian: postgresql); a throwaway cluster is
created in a temporary folder and removed afterwards.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from urllib.parse import urlencode
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
# The code whose rating step ``--server-time`` times: this checkout, or a reference one.
CODE = Path(os.environ.get("BENCH_STUDY_CODE", REPO))
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(CODE))
from benchmarks.machine import describe_machine  # noqa: E402
try:
    from studyapp.participants.simulated import Outcome, longest_clip_s, percentile, run_participants  # noqa: E402
except ImportError:  # a reference checkout from before the study app was split into subpackages
    from studyapp.simulated_participants import Outcome, longest_clip_s, percentile, run_participants  # noqa: E402
from tests.throwaway_postgres import free_port, throwaway_postgres  # noqa: E402

TARGET_STEP_MS = 10.0  # server time of one rating step (the answer until the next page is in hand), median
TARGET_P95_S = 0.1  # a watching participant should not notice the wait for the next clip
# The targets' crowds (``--only targets``): their sizes and what each must meet.
LARGE_WATCHING, EMBEDDED_WATCHING = 1000, 200
TARGET_SATURATION_PER_S = 200.0  # gunicorn + PostgreSQL, every participant answering at once
TARGET_LARGE_P95_S = 0.5  # gunicorn + PostgreSQL, 1,000 watching
TARGET_EMBEDDED_P95_S = 0.25  # manage.py serve + SQLite, 200 watching
TARGET_ANSWER_TO_PLAY_MS = 300.0  # a browser's answer until the next clip plays, median
BROWSER_CLIP_S, BROWSER_ANSWERS = 4.0, 12  # the browser participant's clips, and how many it rates
IN_PLACE = {"HTTP_STUDYAPP_NEXT_PAGE": "in-place"}  # path.NEXT_PAGE_HEADER, as the clip pages' script sends it
WATCH_S = 4.0  # a short stimulus clip
CLIPS = 20  # rated clips per participant
URLENCODED = "application/x-www-form-urlencoded"
PARTICIPANTS_PER_PROCESS = 125  # simulated participants (threads) per client process
PARTS = ("server-time", "crowd", "large", "targets", "floor")
FLOOR_S, FLOOR_CLIENTS = 20.0, 32  # the floor's length and its simultaneous clients (threads over two processes)


def compose_gunicorn_options() -> list[str]:
    """The gunicorn options of compose.yaml's web service (the configuration the README
    recommends), read from it, less its address and access log, which each measurement sets."""
    command = yaml.safe_load((REPO / "compose.yaml").read_text())["services"]["web"]["command"]
    options, own = command[2:], {"--bind", "--access-logfile"}
    return [word for i, word in enumerate(options) if word not in own and (i == 0 or options[i - 1] not in own)]


GUNICORN = compose_gunicorn_options()


def django_step(env: dict, *args: str, code: Path = REPO) -> str:
    """Run ``--setup``, ``--count`` or ``--server-time`` of this script in a process of its
    own (one database per process), importing the study app from ``code``; a failed step
    raises with the end of what it wrote to stderr."""
    step = subprocess.run([sys.executable, __file__, *args], env={**env, "BENCH_STUDY_CODE": str(code)}, cwd=code,
                          capture_output=True, text=True)
    if step.returncode:
        raise RuntimeError(f"bench_study.py {' '.join(args)} exited with {step.returncode}:\n{step.stderr[-3000:]}")
    return step.stdout.strip()


def setup_study(participants: int, video: str | None = None, clip_seconds: float = BROWSER_CLIP_S) -> str:
    """Migrate, and create an open 20-clip study whose stimuli exist, with room for
    ``participants``: 90 rated stimuli, 19 of them per participant. Without ``video`` no
    clip is fetched (none exists); with it every clip is a copy of it (``clip_seconds``
    long), in MEDIA_ROOT or, with MEDIA_BUCKET_URL, only in the bucket."""
    import django

    django.setup()
    from django.core.management import call_command

    from tests.study_fixtures import make_study

    call_command("migrate", verbosity=0)
    study = make_study(owner_name="bench", controls=30, clips_per_participant=CLIPS,
                       ratings_per_stimulus=max(40, math.ceil(participants * (CLIPS - 1) / 90) + 2),
                       training_clips=2, clip_seconds=clip_seconds if video else 0.01,
                       video=Path(video) if video else None)
    if video:
        from django.core.files import File
        from django.core.files.storage import default_storage

        from studyapp.server.media_bucket import in_bucket

        for stimulus in study.stimuli.all() if in_bucket() else []:  # the clips only in the bucket
            with stimulus.video_path().open("rb") as stream:
                default_storage.save(stimulus.relative_path, File(stream))
            stimulus.video_path().unlink()
    return study.key


def setup_browser_study(video: str) -> str:
    """Migrate, collect the static files (the pages' scripts, which the server serves from
    STATIC_ROOT as in production), and create an open study whose every clip is ``video``
    (``BROWSER_CLIP_S`` long), with ``BROWSER_ANSWERS`` clips per participant and no practice."""
    import django

    django.setup()
    from django.core.management import call_command

    from tests.study_fixtures import make_study

    call_command("migrate", verbosity=0)
    call_command("collectstatic", interactive=False, verbosity=0)
    study = make_study(owner_name="bench", controls=2 * BROWSER_ANSWERS, clips_per_participant=BROWSER_ANSWERS,
                       ratings_per_stimulus=40, training_clips=0, clip_seconds=BROWSER_CLIP_S, video=Path(video))
    return study.key


def count_ratings() -> str:
    import django

    django.setup()
    from studyapp.models import Rating

    ratings = Rating.objects.all()
    distinct = ratings.values("assignment_id").distinct().count()
    return json.dumps({"ratings": ratings.count(), "distinct_assignments": distinct})


def server_time(participants: int = 10) -> str:
    """Time rating steps inside this process: ``participants`` in turn through the study."""
    import django

    django.setup()
    from django.db import connection
    from django.test import Client
    from django.test.utils import CaptureQueriesContext

    key = setup_study(participants)
    wall, cpu, queries, commits = [], [], [], []
    for n in range(participants):
        client = Client(enforce_csrf_checks=True, HTTP_HOST="127.0.0.1")
        page = client.get(f"/p/{key}/", {"PROLIFIC_PID": f"one-{n}"}, follow=True).content.decode()
        steps = 0
        while (form := _form(page)) is not None:
            action, data = form
            if not action.endswith("/rate/"):
                page = client.post(action, urlencode(data), content_type=URLENCODED, follow=True).content.decode()
                continue
            time.sleep(longest_clip_s(page))  # the clip plays before the buttons unlock (not timed)
            # The first step of each participant counts queries (capturing slows it down).
            capture = CaptureQueriesContext(connection) if steps == 0 else contextlib.nullcontext()
            with capture as captured:
                start_wall, start_cpu = time.perf_counter(), time.process_time()
                response = client.post(action, urlencode(data), content_type=URLENCODED, **IN_PLACE)
                assert response.status_code in (200, 302), response.content.decode()[:500]
                page = (response.content if response.status_code == 200
                        else client.get(response["Location"]).content).decode()
                if steps:
                    wall.append(time.perf_counter() - start_wall)
                    cpu.append(time.process_time() - start_cpu)
            if steps == 0:
                statements = [query["sql"] for query in captured.captured_queries]
                queries.append(len(statements))
                commits.append(_commits(statements) if connection.vendor == "sqlite" else None)
            steps += 1
    return json.dumps({"steps": len(wall), "median_ms": 1000 * statistics.median(wall),
                       "p95_ms": 1000 * percentile(wall, 0.95), "cpu_median_ms": 1000 * statistics.median(cpu),
                       "queries": statistics.median(queries), "commits": commits[0]})


def _commits(statements: list[str]) -> int:
    """Transactions that wrote, among SQLite's statements as Django logs them: each COMMIT,
    and each write made outside BEGIN ... COMMIT (a transaction of its own)."""
    count, inside = 0, False
    for sql in statements:
        verb = sql.split(None, 1)[0].upper()
        if verb == "BEGIN":
            inside = True
        elif verb in ("COMMIT", "ROLLBACK"):
            count += verb == "COMMIT"
            inside = False
        elif verb in ("INSERT", "UPDATE", "DELETE") and not inside:
            count += 1
    return count


def _form(page: str) -> tuple[str, dict] | None:
    """The action and the answers of a participant page's form, as a quick participant gives them."""
    match = re.search(r'<form method="post" action="([^"]+)"[^>]*>(.*?)</form>', page, re.S)
    if match is None:
        return None
    data = dict(re.findall(r'<input type="hidden" name="([^"]+)" value="([^"]*)">', match.group(2)))
    data.update(agree="yes", value="3", started_s="0.05", ended_s="0.5", answered_s="0.6", played_until_s="0.45")
    return match.group(1), data


@contextlib.contextmanager
def serving(command: list[str], env: dict, port: int, log: Path, code: Path = REPO) -> Iterator[tuple[str, int]]:
    """The server of ``code`` running for the length of the block, its output in ``log``
    (a file: a pipe nobody reads would fill and stall the server's request threads);
    yields its URL and process id."""
    with log.open("wb") as output:
        process = subprocess.Popen(command, env=env, cwd=code, stdout=output, stderr=subprocess.STDOUT,
                                   start_new_session=True)
        url = f"http://127.0.0.1:{port}"
        try:
            for _ in range(300):
                with contextlib.suppress(OSError):
                    urllib.request.urlopen(f"{url}/health.json", timeout=2)
                    break
                if process.poll() is not None:
                    raise RuntimeError(f"the server exited: {log.read_text()[-2000:]}")
                time.sleep(0.1)
            yield url, process.pid
        finally:
            process.terminate()
            process.wait(timeout=60)


def tree_cpu_s(pid: int) -> float:
    """CPU seconds of a process and its descendants, living and exited (reaped by their parents)."""
    tick = os.sysconf("SC_CLK_TCK")
    total, children = 0.0, {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, IndexError, ValueError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
            if int(stat.parent.name) == pid:
                total += sum(int(f) for f in fields[11:15]) / tick  # utime stime cutime cstime
    return total + sum(tree_cpu_s(child) for child in children.get(pid, []))


def server_errors(log: Path) -> list[str]:
    """Each distinct error a server logged ("Internal Server Error: /path", then the
    exception its traceback ends in), with how often it happened."""
    counts: dict[str, int] = {}
    lines = log.read_text(errors="replace").splitlines()
    for i, line in enumerate(lines):
        if line.startswith("Internal Server Error: "):
            end = next((j for j in range(i + 1, len(lines)) if lines[j].startswith(("[", "Internal Server Error"))),
                       len(lines))
            causes = [text for text in lines[i + 1:end] if re.match(r"^[\w.]+(Error|Exception): ", text)]
            key = f"{line.split(': ', 1)[1].split('/')[-2] or '/'}: {causes[-1] if causes else 'no traceback'}"
            counts[key] = counts.get(key, 0) + 1
    return [f"{count} x {key}" for key, count in counts.items()]


def crowd(entry_url: str, participants: int, watch_s: float,
          participant: Callable | None = None) -> tuple[list[Outcome], float]:
    """Run the participants in client processes of their own; their outcomes and CPU seconds.
    ``participant`` makes each (default: run_participants' own, who download no clip)."""
    processes = math.ceil(participants / PARTICIPANTS_PER_PROCESS)
    shares = [participants // processes + (i < participants % processes) for i in range(processes)]
    makers = [[participant] * processes] if participant else []  # a reference checkout's takes none
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with ProcessPoolExecutor(max_workers=processes) as pool:
        batches = list(pool.map(run_participants, [entry_url] * processes, shares, [None] * processes,
                                ["PROLIFIC_PID"] * processes, [f"sim{i}" for i in range(processes)],
                                [watch_s] * processes, *makers))
    after = resource.getrusage(resource.RUSAGE_CHILDREN)  # the pool's processes, reaped at its end
    cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return [outcome for batch in batches for outcome in batch], cpu_s


def server_env(database_url: str, code: Path = REPO, **extra: str) -> dict:
    """The environment of ``code``'s server and of this script's steps run with it."""
    return {**os.environ, "DATABASE_URL": database_url, "DJANGO_SETTINGS_MODULE": settings_module(code),
            "DEBUG": "false", "SECRET_KEY": "benchmark-only-secret-key-" + "x" * 40, "ALLOWED_HOSTS": "127.0.0.1",
            **extra}


def server_command(server: str, port: int, code: Path = REPO) -> list[str]:
    """gunicorn as compose.yaml runs it, or ``manage.py serve`` as ``make demo`` does."""
    if server == "gunicorn":
        wsgi = settings_module(code).rsplit(".", 1)[0] + ".wsgi"
        return [sys.executable, "-m", "gunicorn", wsgi, "--bind", f"127.0.0.1:{port}", *GUNICORN]
    return [sys.executable, "manage.py", "serve", "--noreload", f"127.0.0.1:{port}"]


def measure(name: str, database_url: str, server: str, participants: int, watch_s: float,
            postmaster_pid: Path | None = None, code: Path = REPO) -> dict:
    env = server_env(database_url, code)
    key = django_step(env, "--setup", str(participants), code=code)
    port = free_port()
    command = server_command(server, port, code)
    database_pid = int(postmaster_pid.read_text().split()[0]) if postmaster_pid else None
    with tempfile.TemporaryDirectory(prefix="bench-server-") as folder:
        log = Path(folder) / "server.log"
        with serving(command, env, port, log, code) as (url, server_pid):
            server_before = tree_cpu_s(server_pid)
            database_before = tree_cpu_s(database_pid) if database_pid else 0.0
            start = time.perf_counter()
            outcomes, participants_cpu_s = crowd(f"{url}/p/{key}/", participants, watch_s)
            seconds = time.perf_counter() - start
            server_cpu_s = tree_cpu_s(server_pid) - server_before
            database_cpu_s = tree_cpu_s(database_pid) - database_before if database_pid else 0.0
        errors_logged = server_errors(log)
    latencies = [s for o in outcomes for s in o.rating_latencies_s]
    stored = json.loads(django_step(env, "--count", code=code))
    submitted = sum(o.ratings for o in outcomes)
    machine_s = seconds * len(os.sched_getaffinity(0))
    return {
        "setup": name, "code": "reference" if code != REPO else "this",
        "load": f"watching {watch_s:g} s" if watch_s else "saturation",
        "participants": participants, "finished": sum(o.finished for o in outcomes),
        "errors": [o.error for o in outcomes if o.error][:3], "error_count": sum(bool(o.error) for o in outcomes),
        "server_errors": errors_logged, "ratings_submitted": submitted,
        "ratings_stored": stored["ratings"], "exactly_stored": stored["ratings"] == stored["distinct_assignments"] == submitted,
        "seconds": seconds, "ratings_per_s": submitted / seconds,
        "median_ms": 1000 * percentile(latencies, 0.5), "p95_ms": 1000 * percentile(latencies, 0.95),
        "cpu_share": {"participants": participants_cpu_s / machine_s, "server": server_cpu_s / machine_s,
                      "database": database_cpu_s / machine_s},
        # What a rating costs the server and the database, which a loaded machine's
        # other work stretches less than the latencies (every page of the run counted in).
        "server_cpu_ms_per_rating": 1000 * (server_cpu_s + database_cpu_s) / max(submitted, 1),
    }


def floor_client(base_url: str, first: int, threads: int, seconds: float) -> int:
    """``threads`` clients posting answers to /floor/ for ``seconds``, each a new
    connection as the simulated participants' are; how many were answered."""
    import http.cookiejar
    import threading

    answered = [0] * threads

    def client(n: int) -> None:
        opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))
        token = opener.open(f"{base_url}/floor/?n={first + n}", timeout=30).read().decode()
        body = urlencode({"csrfmiddlewaretoken": token, "value": 3}).encode()
        stop = time.perf_counter() + seconds
        while time.perf_counter() < stop:
            opener.open(f"{base_url}/floor/", data=body, timeout=30).read()
            answered[n] += 1

    workers = [threading.Thread(target=client, args=(n,)) for n in range(threads)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    return sum(answered)


def measure_floor() -> dict:
    """The production shape's requests per second and CPU per request on the floor's page."""
    with throwaway_postgres() as (database_url, pid_file), tempfile.TemporaryDirectory(prefix="bench-floor-") as folder:
        env = server_env(database_url, DJANGO_SETTINGS_MODULE="benchmarks.stack_floor_settings")
        django_step(env, "--setup-floor")
        port = free_port()
        database_pid = int(pid_file.read_text().split()[0])
        with serving(server_command("gunicorn", port), env, port, Path(folder) / "server.log") as (url, server_pid):
            server_before, database_before = tree_cpu_s(server_pid), tree_cpu_s(database_pid)
            processes = 2
            start = time.perf_counter()
            with ProcessPoolExecutor(max_workers=processes) as pool:
                answered = sum(pool.map(floor_client, [url] * processes, range(0, FLOOR_CLIENTS, FLOOR_CLIENTS // processes),
                                        [FLOOR_CLIENTS // processes] * processes, [FLOOR_S] * processes))
            seconds = time.perf_counter() - start
            server_cpu_s = tree_cpu_s(server_pid) - server_before
            database_cpu_s = tree_cpu_s(database_pid) - database_before
    return {"requests": answered, "seconds": seconds, "requests_per_s": answered / seconds,
            "server_cpu_ms": 1000 * server_cpu_s / answered, "database_cpu_ms": 1000 * database_cpu_s / answered}


def setup_floor() -> str:
    """Migrate (the study app's pages are served beside the floor's) and create the floor's tables."""
    import django

    django.setup()
    from django.core.management import call_command

    from benchmarks.stack_floor import create_tables

    call_command("migrate", verbosity=0)
    create_tables()
    return "ready"


# Installed in every document the browser opens: each answer's moment (the submit event)
# and the next clip's first "playing" event, on the clock shared by the tab's documents
# (timeOrigin + now), so that a page swapped in and a page loaded anew are timed alike.
ANSWER_TO_PLAY = """
addEventListener("submit", (event) => {
  if (event.target.action.endsWith("/rate/")) sessionStorage.setItem("answered", performance.timeOrigin + performance.now());
}, true);
addEventListener("playing", (event) => {
  const answered = sessionStorage.getItem("answered");
  if (event.target.id !== "clip" || answered === null) return;
  sessionStorage.removeItem("answered");
  const gaps = JSON.parse(sessionStorage.getItem("gaps") || "[]");
  gaps.push(performance.timeOrigin + performance.now() - Number(answered));
  sessionStorage.setItem("gaps", JSON.stringify(gaps));
}, true);
"""


def render_browser_clip(folder: Path) -> Path:
    """A ``BROWSER_CLIP_S`` clip of real motion at the study's size (the first BVH file under $MOTION_DATA)."""
    from generation.motion.data.clip_files import load_body_motion
    from generation.render import render_video

    data = Path(os.environ.get("MOTION_DATA", str(REPO.parent / "shared" / "data" / "bandai-namco-1")).split(":")[0])
    bvh = next(iter(sorted(data.rglob("*.bvh"))), None)
    if bvh is None:
        raise SystemExit(f"answer to play: no BVH file under {data} (set MOTION_DATA)")
    return render_video(load_body_motion(bvh, fps=20.0, seconds=BROWSER_CLIP_S), folder / "clip.mp4", size=(640, 480))


def answer_to_play(video: Path, code: Path = REPO) -> dict:
    """A participant in headless Chromium rating ``BROWSER_ANSWERS`` clips on ``manage.py
    serve`` + SQLite running ``code``: the time from each answer to the next clip playing."""
    from playwright.sync_api import sync_playwright

    chromium = os.environ.get("CHROMIUM") or shutil.which("chromium")
    if not chromium:
        raise SystemExit("answer to play: Debian's chromium is not installed (scripts/ensure-chromium.sh)")
    with tempfile.TemporaryDirectory(prefix="bench-browser-") as folder:
        env = server_env(f"sqlite:///{folder}/db.sqlite3", code, MEDIA_ROOT=f"{folder}/media",
                         STATIC_ROOT=f"{folder}/static")
        key = django_step(env, "--setup-browser", str(video), code=code)
        port = free_port()
        with serving(server_command("serve", port, code), env, port, Path(folder) / "server.log", code) as (url, _), \
                sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
            page = browser.new_context(viewport={"width": 1366, "height": 768}).new_page()
            page.add_init_script(ANSWER_TO_PLAY)
            page.goto(f"{url}/p/{key}/?PROLIFIC_PID=browser&STUDY_ID=S&SESSION_ID=X")
            page.get_by_role("button", name="I agree to take part").click()
            page.get_by_role("button", name="Start").click()
            for _ in range(BROWSER_ANSWERS):
                token = page.get_attribute("#rating-form input[name=assignment]", "value")
                page.wait_for_function("() => document.getElementById('clip')?.ended", timeout=60_000)
                page.locator("#rating-form button[name=value]").first.click()
                page.wait_for_function(f"() => !document.querySelector(\"#rating-form input[value='{token}']\")",
                                       timeout=60_000)
            page.wait_for_selector("text=You have finished the study")
            gaps = page.evaluate("JSON.parse(sessionStorage.getItem('gaps') || '[]')")
            browser.close()
    return {"code": "reference" if code != REPO else "this", "answers": len(gaps),
            "median_ms": statistics.median(gaps), "p95_ms": percentile(gaps, 0.95), "max_ms": max(gaps)}


def target_rows(participants: int, watch_s: float, reference: Path | None) -> tuple[list[dict], list[dict]]:
    """The targets' crowds and the browser's answer-to-play times, each measured with this
    code and then the reference's (if any)."""
    codes = [REPO, reference] if reference else [REPO]
    rows = []
    for load, crowd_size in ((0.0, participants), (watch_s, LARGE_WATCHING)):
        for code in codes:
            with throwaway_postgres() as (url, pid_file):
                rows.append({**measure("gunicorn + PostgreSQL", url, "gunicorn", crowd_size, load, pid_file, code),
                             "part": "targets"})
    for code in codes:
        with tempfile.TemporaryDirectory(prefix="bench-sqlite-") as folder:
            rows.append({**measure("serve + SQLite", f"sqlite:///{folder}/db.sqlite3", "serve", EMBEDDED_WATCHING,
                                   watch_s, code=code), "part": "targets"})
    with tempfile.TemporaryDirectory(prefix="bench-clip-") as folder:
        video = render_browser_clip(Path(folder))
        plays = [answer_to_play(video, code) for code in codes]
    return rows, plays


def settings_module(code: Path) -> str | None:
    """The Django settings module of a checkout (None: not a checkout of the project); a
    reference checkout may come from before the study app was split into subpackages."""
    for module in ("studyapp.server.settings", "studyapp.settings"):
        if (code / module.replace(".", "/")).with_suffix(".py").is_file():
            return module
    return None


def measure_server_time(name: str, database_url: str, code: Path = REPO) -> dict:
    env = server_env(database_url, code)
    return {"setup": name, "code": "reference" if code != REPO else "this", **json.loads(django_step(env, "--server-time",
                                                                                                    code=code))}


def server_time_rows(rounds: int, reference: Path | None) -> list[dict]:
    """The rating step on SQLite (``rounds`` times, alternating with ``reference``'s code)
    and on PostgreSQL (once each)."""
    codes = [REPO, reference] if reference else [REPO]
    rows = []
    for _ in range(rounds):
        for code in codes:
            with tempfile.TemporaryDirectory(prefix="bench-sqlite-") as folder:
                rows.append(measure_server_time("SQLite", f"sqlite:///{folder}/db.sqlite3", code))
    for code in codes:  # a cluster each: the codes' schemas may differ
        with throwaway_postgres() as (url, _):
            rows.append(measure_server_time("PostgreSQL", url, code))
    return rows


def print_rows(result: dict) -> None:
    print(f"machine: {result['machine']['cpu']}, {result['machine']['cores']} cores; load average "
          f"{result['load_average']}")
    for row in result["server_time"]:
        commits = f", {row['commits']} commits" if row.get("commits") is not None else ""
        print(f"one rating step, server time, {row['setup']:<10} {row['code']:<9} median {row['median_ms']:.1f} ms "
              f"(CPU {row['cpu_median_ms']:.1f} ms), p95 {row['p95_ms']:.1f} ms over {row['steps']} steps, "
              f"{row['queries']:.0f} queries{commits}")
    for row in result["rows"]:
        share = row["cpu_share"]
        print(f"{row['setup']:<24} {row.get('code', 'this'):<9} {row['participants']:>5} {row['load']:<12} "
              f"{row['finished']}/{row['participants']} "
              f"finished, {row['ratings_submitted']} ratings in {row['seconds']:.0f} s = {row['ratings_per_s']:.0f}/s, "
              f"median {row['median_ms']:.0f} ms, p95 {row['p95_ms']:.0f} ms; CPU: participants "
              f"{share['participants']:.0%}, server {share['server']:.0%}, database {share['database']:.0%} "
              f"({row['server_cpu_ms_per_rating']:.0f} ms of server and database CPU a rating); "
              f"database holds exactly the accepted ratings: {row['exactly_stored']}")
        for error in row["errors"]:
            print(f"   error ({row['error_count']} participants): {error}")
        for error in row["server_errors"]:
            print(f"   server: {error}")
    for row in result.get("answer_to_play", []):
        print(f"answer to next clip playing, headless Chromium, serve + SQLite, {row['code']:<9} median "
              f"{row['median_ms']:.0f} ms, p95 {row['p95_ms']:.0f} ms, max {row['max_ms']:.0f} ms over {row['answers']} answers")
    if floor := result.get("floor"):
        print(f"floor, gunicorn + PostgreSQL: {floor['requests_per_s']:.0f} requests/s, "
              f"{floor['server_cpu_ms'] + floor['database_cpu_ms']:.2f} ms of server and database CPU a request "
              f"(server {floor['server_cpu_ms']:.2f}, database {floor['database_cpu_ms']:.2f}), "
              f"{floor['requests']} requests in {floor['seconds']:.0f} s")
        for row in result["rows"]:
            if row["load"] == "saturation" and row["setup"].startswith("gunicorn"):
                print(f"   {row['code']} code at saturation: {row['ratings_per_s'] / floor['requests_per_s']:.0%} of the "
                      f"floor's rate; a rating (every page counted in) costs "
                      f"{row['server_cpu_ms_per_rating'] / (floor['server_cpu_ms'] + floor['database_cpu_ms']):.1f} "
                      f"floor requests of CPU")
    saturated = {row["setup"]: row["ratings_per_s"] for row in result["rows"]
                 if row["load"] == "saturation" and row["part"] == "crowd"}
    if len(saturated) == 2:
        print(f"gunicorn + PostgreSQL: {saturated['gunicorn + PostgreSQL'] / saturated['serve + SQLite']:.2f}x "
              f"the rating throughput of manage.py serve + SQLite at saturation")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", choices=PARTS, action="append",
                        help="run only these parts (repeatable): server-time (the in-process rating step), crowd "
                             "(--participants at saturation and watching, on both setups), large (the --crowds on "
                             "the production shape), targets (the targets' crowds and the browser's answer to play, "
                             "with the --reference-code too, and the floor), floor (the least a rating request "
                             "costs on the production shape); default: all")
    parser.add_argument("--participants", type=int, default=100)
    parser.add_argument("--crowds", default="500,1000",
                        help="larger watching crowds on the production shape, comma-separated ('' for none)")
    parser.add_argument("--watch", type=float, default=WATCH_S,
                        help="seconds each participant spends on a clip's page in the watching runs (default %(default)s)")
    parser.add_argument("--rounds", type=int, default=3,
                        help="server time on SQLite: measurements of each code, alternating (default %(default)s)")
    parser.add_argument("--reference-code", type=Path, metavar="DIR",
                        help="another checkout of the project whose rating step (server-time) and targets' "
                             "crowds and browser (targets) are measured alongside this one's")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--setup", type=int, metavar="PARTICIPANTS", help=argparse.SUPPRESS)
    parser.add_argument("--video", help=argparse.SUPPRESS)
    parser.add_argument("--clip-seconds", type=float, default=BROWSER_CLIP_S, help=argparse.SUPPRESS)
    parser.add_argument("--count", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--server-time", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--setup-browser", metavar="VIDEO", help=argparse.SUPPRESS)
    parser.add_argument("--setup-floor", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.setup is not None or args.count or args.server_time or args.setup_browser or args.setup_floor:
        print(setup_study(args.setup, args.video, args.clip_seconds) if args.setup is not None else count_ratings() if args.count
              else setup_browser_study(args.setup_browser) if args.setup_browser
              else setup_floor() if args.setup_floor else server_time())
        return 0
    if args.reference_code and settings_module(args.reference_code) is None:
        parser.error(f"--reference-code {args.reference_code}: no study app settings there (a checkout of the project?)")

    parts = set(args.only or PARTS)
    load_before = os.getloadavg()
    steps = server_time_rows(args.rounds, args.reference_code.resolve() if args.reference_code else None) \
        if "server-time" in parts else []
    rows = []
    if "crowd" in parts:
        for watch_s in (0.0, args.watch):
            with tempfile.TemporaryDirectory(prefix="bench-sqlite-") as folder:
                rows.append({**measure("serve + SQLite", f"sqlite:///{folder}/db.sqlite3", "serve",
                                       args.participants, watch_s), "part": "crowd"})
            with throwaway_postgres() as (url, pid_file):
                rows.append({**measure("gunicorn + PostgreSQL", url, "gunicorn", args.participants, watch_s, pid_file),
                             "part": "crowd"})
    plays = []
    if "targets" in parts:
        targets, plays = target_rows(args.participants, args.watch,
                                     args.reference_code.resolve() if args.reference_code else None)
        rows += targets
    if "large" in parts:
        for participants in [int(n) for n in args.crowds.split(",") if n.strip()]:  # the big loads last, once
            with throwaway_postgres() as (url, pid_file):
                rows.append({**measure("gunicorn + PostgreSQL", url, "gunicorn", participants, args.watch, pid_file),
                             "part": "large"})
    floor = measure_floor() if parts & {"floor", "targets"} else None
    load = " → ".join(", ".join(f"{x:.1f}" for x in averages) for averages in (load_before, os.getloadavg()))
    result = {"machine": describe_machine(), "load_average": load, "server_time": steps, "rows": rows,
              "answer_to_play": plays, "floor": floor}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print_rows(result)
    return 0 if targets_met(result) else 1


def targets_met(result: dict) -> bool:
    """Print each target of the parts that ran, met or missed; whether all were met.

    Every crowd of this code must store exactly what was accepted and serve every
    participant (the embedded default too: it holds a crowd); the time targets: the
    median rating step on SQLite, the p95 of the watching --participants on the
    production shape, and the targets' (``TARGET_*``).
    """
    checks = []
    ours = [row for row in result["server_time"] if row["setup"] == "SQLite" and row["code"] == "this"]
    if ours:
        medians = sorted(row["median_ms"] for row in ours)
        checks.append((f"rating step on SQLite, median {'–'.join(f'{m:.1f}' for m in (medians[0], medians[-1]))} ms "
                       f"(target ≤ {TARGET_STEP_MS:.0f} ms)", statistics.median(medians) <= TARGET_STEP_MS))
    for row in result["rows"]:
        if row.get("code") == "reference":  # measured beside ours, not held to the targets
            continue
        checks.append((f"{row['setup']}, {row['participants']} {row['load']}: no error, every rating stored once",
                       row["exactly_stored"] and not row["error_count"] and row["finished"] == row["participants"]))
        watching = row["load"] != "saturation"
        if row["part"] == "crowd" and row["setup"].startswith("gunicorn") and watching:
            checks.append((f"{row['setup']}, {row['participants']} watching: p95 {row['p95_ms']:.0f} ms "
                           f"(target < {TARGET_P95_S * 1000:.0f} ms)", row["p95_ms"] / 1000 < TARGET_P95_S))
        if row["part"] != "targets":
            continue
        if not watching:
            checks.append((f"{row['setup']} at saturation: {row['ratings_per_s']:.0f} ratings/s "
                           f"(target >= {TARGET_SATURATION_PER_S:.0f})", row["ratings_per_s"] >= TARGET_SATURATION_PER_S))
        else:
            target = TARGET_LARGE_P95_S if row["setup"].startswith("gunicorn") else TARGET_EMBEDDED_P95_S
            checks.append((f"{row['setup']}, {row['participants']} watching: p95 {row['p95_ms']:.0f} ms "
                           f"(target < {target * 1000:.0f} ms)", row["p95_ms"] / 1000 < target))
    for row in result.get("answer_to_play", []):
        if row["code"] == "this":
            checks.append((f"answer to next clip playing in a browser: median {row['median_ms']:.0f} ms (target < "
                           f"{TARGET_ANSWER_TO_PLAY_MS:.0f} ms)", row["median_ms"] < TARGET_ANSWER_TO_PLAY_MS))
    for text, met in checks:
        print(f"{'met' if met else 'MISSED'}: {text}")
    return all(met for _, met in checks)


if __name__ == "__main__":
    raise SystemExit(main())
