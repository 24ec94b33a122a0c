"""``manage.py serve [addrport] [--workers N] [--threads N] [--noreload]``: the study app
served by gunicorn, one process per core (up to four), as ``make demo`` serves it.

Django's runserver answers every request in one process, so one core's worth of Python
(its interpreter lock) was the embedded default's limit: 200 participants watching 4-s
clips ask about 48 ratings a second, runserver answered 32 and their answers queued (p95
1.95 s; benchmarks/bench_study.py). gunicorn's threaded workers, one process per core,
answer them at p95 100 ms on the same machine (README, the benchmark table).

The command keeps what runserver did for the demo: its address argument (``8000``,
``0.0.0.0:8000``, ``[::1]:8000``), its checks (the system checks, unapplied migrations),
the apps' static files served with DEBUG on (or ``--insecure``), reloading on a change of
the code (gunicorn's reloader; ``--noreload`` turns it off) and a listen queue long enough
for a crowd's connections opened at once. SQLite's writers of one process take turns
(``studyapp.server.db.sqlite_backend``); SQLite's busy timeout arbitrates between the processes.
"""

from __future__ import annotations

import os
import socket

from django.contrib.staticfiles.management.commands.runserver import Command as RunserverCommand
from django.core.management.base import CommandError
from django.db import connections
from gunicorn.app.base import BaseApplication

from studyapp.server.gc_tuning import freeze_start_up

THREADS = 16  # per process: a thread waits while a participant's phone downloads a clip
# One process per core, up to four: each holds about 170 MB, and on SQLite one of them
# writes at a time, so a workstation's many cores would add memory more than answers.
WORKERS = min(len(os.sched_getaffinity(0)), 4)


def _check_listening(host: str, port: str) -> None:
    """Refuse, on one line, an address this machine cannot listen on (gunicorn would retry
    it for five seconds and end with a log line)."""
    try:
        family = socket.getaddrinfo(host, int(port), type=socket.SOCK_STREAM)[0][0]
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as gunicorn binds
            probe.bind((host, int(port)))  # not getaddrinfo's address, whose port wraps at 65536
    except (OSError, OverflowError) as error:
        reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
        raise CommandError(f"cannot serve at {host}:{port}: {reason}", returncode=2) from None


class _Gunicorn(BaseApplication):
    """gunicorn serving one WSGI handler with the settings given (no command line or file read)."""

    def __init__(self, handler, settings: dict) -> None:
        self.handler, self.settings = handler, settings
        super().__init__()

    def load_config(self) -> None:
        for name, value in self.settings.items():
            self.cfg.set(name, value)

    def load(self):
        return self.handler


class Command(RunserverCommand):
    help = ("Serve the study app with gunicorn: one process per core (--workers), each with --threads threads; "
            "the apps' static files with DEBUG on, as runserver serves them.")

    def add_arguments(self, parser) -> None:
        super().add_arguments(parser)
        parser.add_argument("--workers", type=int, default=WORKERS,
                            help="server processes (default: one per core of this machine, at most 4: %(default)s)")
        parser.add_argument("--threads", type=int, default=THREADS,
                            help="threads per process (default %(default)s; --nothreading: 1)")

    def handle(self, *args, **options) -> None:
        for option in ("workers", "threads"):
            if options[option] < 1:
                raise CommandError(f"--{option} {options[option]}: give a whole number of at least 1", returncode=2)
        try:
            super().handle(*args, **options)
        except CommandError as error:  # runserver's refusal of the address, status 2 as every refusal here
            raise CommandError(str(error), returncode=2) from None

    def run(self, **options) -> None:
        # gunicorn's arbiter must own the main thread (its signals), where Django's
        # reloader would run the server in another; gunicorn reloads on its own.
        self.inner_run(None, **options)

    def inner_run(self, *args, **options) -> None:
        if not options["skip_checks"]:
            self.check(display_num_errors=True)
        self.check_migrations()
        connections.close_all()  # the workers are forked: none may inherit the checks' connections
        freeze_start_up()
        host = "0.0.0.0" if self.addr == "0" else self.addr
        _check_listening(host, self.port)
        address = f"[{host}]" if self._raw_ipv6 else host
        threads = options["threads"] if options["use_threading"] else 1
        self.stdout.write(f"Serving the study app at {self.protocol}://{address}:{self.port}/ with gunicorn, "
                          f"{options['workers']} processes of {threads} threads; quit with CONTROL-C.")
        _Gunicorn(self.get_handler(*args, **options), {
            "bind": f"{address}:{self.port}",
            "workers": options["workers"], "worker_class": "gthread", "threads": threads,
            "backlog": 1024,  # the kernel caps it at net.core.somaxconn (4096 on current Linux)
            "reload": options["use_reloader"],
            "graceful_timeout": 5,  # a stopped demo does not wait half a minute for open connections
            "control_socket_disable": True,  # one path per user: two servers side by side would share it
        }).run()
