"""``make demo``: the main job on embedded defaults, from real motion capture to a web page.

1. migrates the SQLite database under var/;
2. builds the MoGlow locomotion dataset from $MOTION_DATA (cached after the first run);
3. starts one local Celery worker on the serverless filesystem broker;
4. has the worker render a gallery of natural clips (one per content label);
5. makes sure a researcher account exists (for the analysis pages);
6. serves the gallery and the health page with Django's runserver until Ctrl-C.
"""

from __future__ import annotations

import os
import secrets
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import django

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "data" / "bandai-namco-1"
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right")


def say(text: str) -> None:
    print(f"[demo] {text}", flush=True)


def motion_folder() -> Path | None:
    folder = Path(os.environ.get("MOTION_DATA", DEFAULT_DATA))
    return folder if folder.is_dir() else None


def start_worker() -> subprocess.Popen:
    command = [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool=solo",
               "--loglevel=warning", "--hostname=demo@%h"]
    return subprocess.Popen(command, cwd=REPO, start_new_session=True)


def wait_for_worker(app, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if app.control.ping(timeout=1.0):
            return
    raise RuntimeError("the Celery worker did not answer within a minute; see its log above")


def render_gallery(data: Path, media_root: Path) -> int:
    from tqdm import tqdm

    from generation.gallery import GalleryOptions, choose_clips, write_index
    from studyapp.tasks import render_natural_clip

    options = GalleryOptions()
    out = media_root / "gallery"
    clips = choose_clips(data, options.per_content, options.contents, options.seconds)
    pending = [render_natural_clip.delay(str(p), str(out), options.to_dict()) for p in clips]
    entries = []
    with tqdm(total=len(pending), desc="worker rendering gallery", unit="clip") as bar:
        for result in pending:
            entries.append(result.get(timeout=600))
            bar.update()
    write_index(out, entries)
    return len(entries)


def ensure_researcher(var_dir: Path) -> tuple[str, str]:
    """The demo's researcher login; the password is made once and kept under var/."""
    from django.contrib.auth.models import User

    name = "researcher"
    secret = var_dir / "demo-researcher-password.txt"
    if not secret.exists():
        secret.write_text(secrets.token_urlsafe(12))
        secret.chmod(0o600)
    password = secret.read_text().strip()
    user, _ = User.objects.get_or_create(username=name)
    if not user.check_password(password):
        user.set_password(password)
        user.save()
    return name, password


def port_is_free(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


def stop(process: subprocess.Popen | None) -> None:
    if process is None or process.poll() is not None:
        return
    os.killpg(process.pid, signal.SIGTERM)
    try:
        process.wait(timeout=15)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()


def interrupt(signum, frame) -> None:
    raise KeyboardInterrupt  # so that a SIGTERM, too, stops the worker and the server


def main() -> int:
    signal.signal(signal.SIGTERM, interrupt)
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.settings")
    django.setup()
    from django.conf import settings
    from django.core.management import call_command

    from generation.motion.dataset import DatasetOptions, build_dataset
    from studyapp.celery import app

    data = motion_folder()
    if data is None:
        say("no motion data found. Get the Bandai-Namco Research Motion Dataset 1 from GitHub "
            "(BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset) or use any folder of "
            "BVH files, then run:  MOTION_DATA=/path/to/folder make demo")
        return 1
    port = int(os.environ.get("DEMO_PORT", "8000"))
    if not port_is_free(port):
        say(f"port {port} is in use; choose another with DEMO_PORT=8001 make demo")
        return 1

    say(f"database: {settings.DATABASES['default']['NAME']}")
    call_command("migrate", verbosity=0)
    login = ensure_researcher(Path(settings.VAR_DIR))
    say(f"building the locomotion dataset from {data}")
    dataset = build_dataset(data, DatasetOptions(contents=LOCOMOTION))
    say(f"dataset {dataset.fingerprint[:12]}: {len(dataset.select('train', augmented=False))} training takes, "
        f"{len(dataset.select('test'))} held out, {len(dataset.windows('train')['pose'])} training windows")

    worker = server = None
    try:
        say("starting one Celery worker (filesystem broker under var/broker)")
        worker = start_worker()
        wait_for_worker(app)
        count = render_gallery(data, Path(settings.MEDIA_ROOT))
        say(f"{count} natural clips rendered into {Path(settings.MEDIA_ROOT) / 'gallery'}")
        server = subprocess.Popen(
            [sys.executable, "manage.py", "runserver", "--noreload", f"127.0.0.1:{port}"],
            cwd=REPO, start_new_session=True,
        )
        say(f"gallery:  http://127.0.0.1:{port}/")
        say(f"health:   http://127.0.0.1:{port}/health/")
        say(f"analysis: http://127.0.0.1:{port}/analysis/  (login {login[0]} / {login[1]})")
        say("press Ctrl-C to stop")
        server.wait()
    except KeyboardInterrupt:
        say("stopping")
    finally:
        stop(server)
        stop(worker)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
