"""Every documented way of serving a study holds a crowd arriving at once: 100 new
connections opened together each get an answer, even while the server's processes
cannot accept them (paused, as on a loaded machine), which is when a short listen queue
drops them (Django's runserver queues 10: about 90 of 100 are lost this way).

The ways are those the documentation names: ``manage.py serve`` (what ``make demo``
runs), gunicorn as ``compose.yaml``'s web service runs it, and gunicorn as the image's
own command (``Dockerfile``). The commands are read from those files, so a change there
is what is tested. Each server runs on the embedded SQLite database in a fresh folder;
every connection asks for a participant page (an unknown study's, one database query).
``manage.py serve`` also answers from as many processes as it is asked for, and serves
the apps' static files with DEBUG on, as Django's runserver did before it.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import pytest
import yaml

from tests.conftest import REPO
from tests.test_study_worker import children

CONNECTIONS = 100
CONNECT_TIMEOUT_S = 3.0  # past the kernel's first SYN retry (1 s): a dropped connection stays dropped
ANSWER_TIMEOUT_S = 60.0


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _with_bind(command: list[str], port: int) -> list[str]:
    """A gunicorn command of the docs, bound to a local port instead of the container's."""
    command = [word for word in command if not word.startswith("0.0.0.0:")]
    if "--bind" in command:
        command.remove("--bind")
    return [sys.executable, "-m", *command, "--bind", f"127.0.0.1:{port}"]


def compose_web_command(port: int) -> list[str]:
    compose = yaml.safe_load((REPO / "compose.yaml").read_text())
    return _with_bind(compose["services"]["web"]["command"], port)


def dockerfile_command(port: int) -> list[str]:
    cmd = re.search(r"^CMD (\[.*\])$", (REPO / "Dockerfile").read_text(), re.MULTILINE)
    return _with_bind(json.loads(cmd.group(1)), port)


def manage_serve_command(port: int) -> list[str]:
    return [sys.executable, "manage.py", "serve", "--noreload", f"127.0.0.1:{port}"]


SERVERS = {"manage.py serve (make demo)": manage_serve_command, "gunicorn as compose.yaml's web": compose_web_command,
           "gunicorn as the Dockerfile's command": dockerfile_command}


@pytest.fixture(scope="module")
def environment(tmp_path_factory) -> dict[str, str]:
    """The embedded defaults in a fresh folder, its database migrated."""
    var = tmp_path_factory.mktemp("serving") / "var"
    env = {**os.environ, "STUDYAPP_VAR_DIR": str(var), "MEDIA_ROOT": str(var / "media"), "DEBUG": "0",
           "ALLOWED_HOSTS": "127.0.0.1"}
    env.pop("DATABASE_URL", None)
    subprocess.run([sys.executable, "manage.py", "migrate", "--noinput", "-v", "0"], cwd=REPO, env=env, check=True)
    return env


def _wait_until_listening(port: int, server: subprocess.Popen, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise RuntimeError(f"the server exited with status {server.returncode}")
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1):
                return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"nothing listens on port {port} after {timeout_s:g} s")


def burst(port: int, server: subprocess.Popen, count: int = CONNECTIONS) -> list[str]:
    """Open ``count`` connections together while the server's processes are paused, as on a
    machine too loaded to let them accept (only the kernel's listen queue holds the crowd),
    then let them go on and send a request on each; each one's status line, or what went wrong."""
    ready = threading.Barrier(count)
    connections: list[socket.socket | None] = [None] * count
    outcomes = [""] * count

    def connect(index: int) -> None:
        try:
            ready.wait(timeout=30)  # every thread connects at the same moment
            connections[index] = socket.create_connection(("127.0.0.1", port), timeout=CONNECT_TIMEOUT_S)
        except (OSError, threading.BrokenBarrierError) as error:
            outcomes[index] = f"connecting: {type(error).__name__}: {error}"

    def ask(index: int) -> None:
        connection = connections[index]
        if connection is None:
            return
        try:
            with connection:
                connection.settimeout(ANSWER_TIMEOUT_S)
                connection.sendall(b"GET /p/no-such-study/ HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
                answer = b""
                while chunk := connection.recv(65536):
                    answer += chunk
            outcomes[index] = answer.split(b"\r\n", 1)[0].decode() or "no answer"
        except OSError as error:
            outcomes[index] = f"asking: {type(error).__name__}: {error}"

    os.killpg(server.pid, signal.SIGSTOP)
    try:
        _run_together(connect, count)
    finally:
        os.killpg(server.pid, signal.SIGCONT)
    _run_together(ask, count)
    return outcomes


def _run_together(work, count: int) -> None:
    threads = [threading.Thread(target=work, args=(i,)) for i in range(count)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()


@pytest.mark.slow
@pytest.mark.parametrize("command", SERVERS.values(), ids=SERVERS.keys())
def test_every_documented_server_answers_100_connections_opened_at_once(command, environment):
    port = _free_port()
    server = subprocess.Popen(command(port), cwd=REPO, env=environment, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        _wait_until_listening(port, server)
        outcomes = burst(port, server)
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
    answered = [outcome for outcome in outcomes if outcome.startswith("HTTP/1.") and outcome.endswith("404 Not Found")]
    assert len(answered) == CONNECTIONS, sorted(set(outcomes))


def test_the_tested_commands_are_the_documented_ones():
    assert compose_web_command(8000)[2:] == ["gunicorn", "studyapp.server.wsgi", "--workers", "3", "--worker-class",
                                             "gthread", "--threads", "8", "--keep-alive", "75", "--access-logfile",
                                             "-", "--bind",
                                             "127.0.0.1:8000"]
    assert dockerfile_command(8000)[2:] == ["gunicorn", "studyapp.server.wsgi", "--access-logfile", "-", "--bind",
                                            "127.0.0.1:8000"]
    assert "manage.py serve" in (REPO / "docs" / "deploying.md").read_text()
    assert '"manage.py", "serve"' in Path(REPO / "studyapp" / "demo.py").read_text()


def test_gunicorns_workers_import_every_view_when_they_load_the_app_not_in_their_first_request(environment):
    # Else each worker would import them (and the analysis modules behind the researcher
    # pages) while a participant's first request waits, and outside the frozen start-up.
    loaded = subprocess.run([sys.executable, "-c", "import sys, gc, studyapp.server.wsgi; "
                             "print('studyapp.participants.views' in sys.modules, gc.get_freeze_count() > 0)"],
                            cwd=REPO, env=environment, capture_output=True, text=True, timeout=120, check=True)
    assert loaded.stdout.split() == ["True", "True"]


@pytest.mark.slow
def test_manage_py_serve_answers_from_the_processes_asked_for_and_serves_static_files_with_debug_on(environment):
    port = _free_port()
    server = subprocess.Popen([*manage_serve_command(port), "--workers", "3"], cwd=REPO,
                              env={**environment, "DEBUG": "1"}, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        _wait_until_listening(port, server)
        deadline = time.monotonic() + 30
        while len(children(server.pid)) < 3 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert len(children(server.pid)) == 3
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/static/studyapp/site.css", timeout=30) as response:
            assert response.read() == (REPO / "studyapp" / "static" / "studyapp" / "site.css").read_bytes()
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=20)


@pytest.mark.parametrize("option", ["--workers", "--threads"])
def test_manage_py_serve_refuses_fewer_than_one_process_or_thread_with_status_2(option, environment):
    completed = subprocess.run([*manage_serve_command(_free_port()), option, "0"], cwd=REPO, env=environment,
                               capture_output=True, text=True, timeout=60)
    assert completed.returncode == 2
    assert completed.stderr.strip().splitlines()[-1] == f"CommandError: {option} 0: give a whole number of at least 1"


def test_manage_py_serve_refuses_an_address_it_cannot_listen_on_with_status_2_and_one_line(environment):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        refusals = {address: subprocess.run([sys.executable, "manage.py", "serve", "--noreload", address], cwd=REPO,
                                            env=environment, capture_output=True, text=True, timeout=60)
                    for address in (f"127.0.0.1:{port}", "no-such-host.invalid:8000", "abc", "99999")}
    said = {address: (done.returncode, done.stderr.strip()) for address, done in refusals.items()}
    unknown = said.pop("no-such-host.invalid:8000")  # the resolver's own words follow
    assert unknown[0] == 2 and re.fullmatch(r"CommandError: cannot serve at no-such-host\.invalid:8000: [^\n]+", unknown[1])
    assert said == {f"127.0.0.1:{port}": (2, f"CommandError: cannot serve at 127.0.0.1:{port}: Address already in use"),
                    "abc": (2, 'CommandError: "abc" is not a valid port number or address:port pair.'),
                    "99999": (2, "CommandError: cannot serve at 127.0.0.1:99999: bind(): port must be 0-65535.")}
