"""``make demo``: the main job on embedded defaults, from real motion capture to a live study.

1. migrates the SQLite database under var/, collects the static files and makes sure a
   researcher account exists;
2. builds the MoGlow locomotion dataset from $MOTION_DATA (by default the locomotion of
   both Bandai-Namco folders, 1.5 hours; about half a minute, cached after the first run);
3. uses the project's own models (models/: the ``cpu`` MoGlow, trained on that data for
   hours, and the ``cpu`` RNN and VAE and an early MoGlow for the BAD clips, trained on
   the same data and split by ``make demo-models``), checked against their recorded
   digests and the data; it trains its own only when asked (DEMO_TRAIN=1);
4. starts one local Celery worker on the serverless filesystem broker;
5. has the worker render a gallery of natural clips (one per content label);
6. sets up the demo study (MoGlow, RNN, VAE, NAT and BAD; held-out and synthetic
   control) and has the worker sample and render every stimulus;
7. sets up a side-by-side study beside it (the same systems, controls and clips, rated
   on 0-100 sliders, every system's clip of one control on a page);
8. sets up an appropriateness study (MoGlow, RNN, VAE and NAT; the same controls and
   four more held-out takes, so that takes find partners), reusing the motion already
   sampled, and queues its clips, which the worker renders while the demo serves;
9. opens the studies and serves them with ``manage.py serve`` (gunicorn, a process per core
   up to four, a listen queue that holds a crowd) on DEMO_HOST:DEMO_PORT (all interfaces, port 8000) until
   Ctrl-C, printing the participant links (each with an id of its own, at this machine's
   network address, so they open on a phone of the same network) and the researcher's
   login.
"""

from __future__ import annotations

import hashlib
import os
import secrets
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import django
from django.core.exceptions import ImproperlyConfigured

from studyapp.server.env import env_bool, env_str

REPO = Path(__file__).resolve().parents[1]
# The data the committed MoGlow learnt from, prepared as it was (README, "Trained on the
# real data"): the locomotion of both Bandai-Namco folders, windows overlapping by
# three quarters, mirrored and reversed.
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right", "walk-turn-left", "walk-turn-right")
DATASET = {"contents": LOCOMOTION, "overlap": 0.75, "mirror": True, "reverse": True}
DEMO_STUDY = "Demo: naturalness of generated locomotion"
SIDE_BY_SIDE_STUDY = "Demo: naturalness of generated locomotion, side by side"
SIDE_BY_SIDE_INSTRUCTIONS = (
    "Each page shows several short videos of a stick figure moving. Play every video to its end (playing one "
    "pauses the others), then rate how natural each one looks on its slider, from 0 (completely unnatural) to 100 "
    "(completely natural). Compare them with each other: the videos on one page follow the same path.")
# (system name, model kind, role, committed file, training steps). Every demo model is
# committed under COMMITTED_MODELS with its digest in SHA256SUMS, trained by
# scripts/train-demo-models.sh (`make demo-models`; MoGlow as the README's "Trained on the
# real data" says): the RNN and VAE keep their state of lowest validation loss, the BAD
# system is MoGlow stopped after a few steps, whose motion is visibly broken. The demo
# trains its own, with these steps, into var/models only when asked (DEMO_TRAIN=1), should a
# committed file be missing, changed, or learnt from other data than $MOTION_DATA.
DEMO_MODELS = (("MoGlow", "moglow", "model", "moglow-cpu.safetensors", 4000),
               ("RNN", "rnn", "model", "rnn-cpu.safetensors", 400),
               ("VAE", "vae", "model", "vae-cpu.safetensors", 1000),
               ("BAD", "moglow", "bad", "moglow-bad.safetensors", 15))
COMMITTED_MODELS = REPO / "models"
DIGESTS = COMMITTED_MODELS / "SHA256SUMS"
# What a demo model trained when asked keeps: the baselines their best state, MoGlow and BAD their last.
KEEPS_BEST = {"rnn", "vae"}
# Held-out clips start 1 s into their takes, the models warming up on that first second,
# as the MoGlow authors sample a test take (many walks start slower than they go on).
HELD_OUT_CONTROLS, CONTROL_SECONDS, HELD_OUT_LEAD_IN = 4, 6.0, 1.0
SYNTHETIC_CONTROLS = ("walk-circle", "walk-backward", "stand-still", "sidestep-left")
APPROPRIATENESS_STUDY = "Demo: does the generated locomotion follow its path?"
# Of four held-out takes (one walk, run, dash and backward walk) none is like another; eight
# add turns and sidesteps both ways, which pair up.
APPROPRIATENESS_HELD_OUT = 8
APPROPRIATENESS_INSTRUCTIONS = (
    "Each page shows the same character twice. The orange band on the floor is the path it was asked to follow: in "
    "one clip its motion was made for that path, in the other for another path. Play both clips to their end, then "
    "say which one fits the path better, and whether slightly or clearly.")


def say(text: str) -> None:
    print(f"[demo] {text}", flush=True)


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


def render_gallery(data: str, media_root: Path) -> int:
    from tqdm import tqdm

    from generation.gallery import GalleryOptions, choose_clips, with_figure, write_index
    from studyapp.tasks import render_natural_clip

    options = GalleryOptions()
    out = media_root / "gallery"
    clips = choose_clips(data, options.per_content, options.contents, options.seconds, options.min_seconds)
    options = with_figure(options, clips)  # every worker draws the first clip's figure
    pending = [render_natural_clip.delay(str(p), str(out), options.to_dict()) for p in clips]
    entries = []
    with tqdm(total=len(pending), desc="worker rendering gallery", unit="clip") as bar:
        for result in pending:
            entries.append(result.get(timeout=600))
            bar.update()
    write_index(out, entries)
    return len(entries)


class DemoStop(Exception):
    """The demo cannot go on without something only the user can do; the message says what."""


def recorded_digests() -> dict[str, str]:
    """The committed models' SHA-256 digests by file name (models/SHA256SUMS)."""
    lines = DIGESTS.read_text().splitlines() if DIGESTS.is_file() else []
    return {name.strip(): digest for digest, name in (line.split(maxsplit=1) for line in lines if line.strip())}


def committed_model(file: str, fingerprint: str) -> tuple[Path | None, str]:
    """The committed checkpoint ``file`` where it is whole (its recorded digest) and learnt
    from the data of this ``fingerprint`` (held-out controls of other data could be its
    training clips); else None and why not."""
    from generation.checkpoint import read_meta

    path = COMMITTED_MODELS / file
    shown = path.relative_to(REPO)
    if not path.is_file():
        return None, f"{shown} is missing"
    recorded = recorded_digests().get(file)
    if recorded is None or hashlib.sha256(path.read_bytes()).hexdigest() != recorded:
        return None, f"{shown} is not the file whose digest {DIGESTS.relative_to(REPO)} records (git checkout models/)"
    if read_meta(path).data_fingerprint != fingerprint:
        return None, f"{shown} learnt from other data (the locomotion of both Bandai-Namco folders) than $MOTION_DATA holds"
    return path, ""


def trained_path(models: Path, kind: str, steps: int) -> Path:
    """Where a demo model trained when asked is kept: its last or best state."""
    return models / f"{kind}-cpu-{steps}steps{'.best' if kind in KEEPS_BEST else ''}.safetensors"


def ensure_models(dataset, models: Path, train_if_needed: bool = False) -> dict[str, Path]:
    """Each demo system's checkpoint: the committed one, or, where that does not fit and
    ``train_if_needed``, one trained on the demo's data (minutes each on 2 cores, MoGlow about
    an hour); DemoStop naming what does not fit otherwise."""
    from generation.checkpoint import read_meta
    from generation.train import TrainOptions, train

    checkpoints, unfit = {}, []
    for name, kind, _, file, steps in DEMO_MODELS:
        committed, why = committed_model(file, dataset.fingerprint)
        if committed is not None:
            checkpoints[name] = committed
            continue
        path = checkpoints[name] = trained_path(models, kind, steps)
        last = path.with_name(path.name.replace(".best", ""))
        if path.exists() and read_meta(last).step >= steps:
            continue
        if not train_if_needed:
            unfit.append(f"{name}: {why}")
            continue
        # A run stopped part-way (Ctrl-C) goes on from its last checkpoint instead of being taken as trained.
        resume = last.exists()
        say(f"{why}: {'continuing' if resume else 'training'} {name} ({kind}, cpu preset, {steps} steps) on the "
            f"demo's data, once, kept in {models}")
        train(kind, "cpu", dataset, last, TrainOptions(steps=steps, eval_every=min(steps, 250)), resume=resume)
    if unfit:
        raise DemoStop("; ".join(unfit) + ". Train the demo's own models on $MOTION_DATA with "
                       "DEMO_TRAIN=1 make demo (minutes for RNN, VAE and BAD, about an hour for MoGlow), "
                       "or run the demo on the data the committed models learnt from")
    return checkpoints


def ensure_study(owner, checkpoints: dict[str, Path]):
    """The demo study with its systems and controls, created once; its stimuli generated by the worker."""
    from django.core.management import CommandError, call_command
    from django.db import transaction

    from studyapp.models import Stimulus, Study

    study = Study.objects.filter(owner=owner, title=DEMO_STUDY).first()
    if study is None:
        with transaction.atomic():  # all or nothing, so a failed first run is simply repeated
            study = _create_study(owner, checkpoints)
    say("the worker samples and renders every stimulus (the first time only)")
    try:
        call_command("generate_stimuli", study.pk, wait=True)
    except CommandError as error:  # the study still runs with the clips that were made
        say(str(error))
    done = study.stimuli.filter(status=Stimulus.Status.DONE).count()
    say(f"{done} of {study.stimuli.count()} stimuli rendered")
    study.is_open = done > 0
    study.save(update_fields=["is_open"])
    return study


def _create_study(owner, checkpoints: dict[str, Path]):
    from django.core.files import File

    from studyapp.stimuli.controls import add_held_out_controls, add_preset_controls
    from studyapp.models import Study
    from studyapp.stimuli.systems import add_checkpoint_system, add_natural_system

    study = Study.objects.create(owner=owner, title=DEMO_STUDY, clips_per_participant=12, ratings_per_stimulus=10,
                                 training_clips=3, completion_code="DEMO-DONE")
    for name, _, role, _, _ in DEMO_MODELS:
        path = checkpoints[name]
        with path.open("rb") as stream:
            add_checkpoint_system(study, name, File(stream, name=path.name), role=role)
    add_natural_system(study)
    add_held_out_controls(study, CONTROL_SECONDS, HELD_OUT_CONTROLS, HELD_OUT_LEAD_IN)
    add_preset_controls(study, list(SYNTHETIC_CONTROLS))
    return study


def ensure_side_by_side_study(single):
    """The side-by-side demo study: the single study's systems, controls and rendered clips
    (``duplication.copy_contents``: each clip's file linked under a token of its own), so it
    needs no rendering of its own; clips rendered since the last run are added."""
    from django.db import transaction

    from studyapp.models import Stimulus, Study
    from studyapp.researchers.setup.duplication import copy_contents

    with transaction.atomic():
        study, _ = Study.objects.get_or_create(owner=single.owner, title=SIDE_BY_SIDE_STUDY, defaults={
            "design": "side-by-side", "scale_min": 0, "scale_max": 100, "pages_per_participant": 6,
            "ratings_per_stimulus": 10, "training_clips": 3, "bad_checks": 2, "instructed_checks": 1,
            "instructions": SIDE_BY_SIDE_INSTRUCTIONS, "completion_code": "DEMO-DONE", "camera": single.camera,
            "video_width": single.video_width, "video_height": single.video_height})
        copy_contents(single, study)
        study.is_open = study.stimuli.filter(status=Stimulus.Status.DONE).exists()
        study.save(update_fields=["is_open"])
    return study


def ensure_appropriateness_study(single):
    """The appropriateness demo study: the single study's systems but BAD, its controls and
    more held-out takes; created once. Its clips are queued, not waited for: the worker
    renders them while the demo serves, and pages are made of the pairs already rendered."""
    from django.db import transaction

    from studyapp.models import Study, System
    from studyapp.stimuli.clips import plan_stimuli
    from studyapp.stimuli.controls import add_held_out_controls, add_preset_controls
    from studyapp.stimuli.dispatch import BrokerUnavailable, queue_stimuli

    study = Study.objects.filter(owner=single.owner, title=APPROPRIATENESS_STUDY).first()
    if study is None:
        with transaction.atomic():
            study = Study.objects.create(
                owner=single.owner, title=APPROPRIATENESS_STUDY, design="appropriateness", pages_per_participant=8,
                ratings_per_stimulus=10, training_clips=2, bad_checks=1, instructions=APPROPRIATENESS_INSTRUCTIONS,
                completion_code="DEMO-DONE", camera=single.camera, video_width=single.video_width,
                video_height=single.video_height)
            for system in single.systems.exclude(role=System.Role.BAD):
                System.objects.create(study=study, name=system.name, role=system.role, checkpoint=system.checkpoint,
                                      checkpoint_digest=system.checkpoint_digest, kind=system.kind,
                                      metadata=system.metadata, temperature=system.temperature)
            add_held_out_controls(study, CONTROL_SECONDS, APPROPRIATENESS_HELD_OUT, HELD_OUT_LEAD_IN)
            add_preset_controls(study, list(SYNTHETIC_CONTROLS))
    stimuli, _ = plan_stimuli(study)
    reused = reuse_sampled_motion(study, single)
    try:
        queued = queue_stimuli(stimuli)
    except BrokerUnavailable as error:
        say(str(error))
        queued = 0
    say(f"appropriateness study: {len(stimuli)} clips ({reused} reusing motion already sampled), {queued} queued; "
        "the worker renders them while the demo serves")
    study.is_open = True
    study.save(update_fields=["is_open"])
    return study


def reuse_sampled_motion(study, single) -> int:
    """Link the motion the single study sampled to the same clips of ``study`` (same
    checkpoint, temperature, control and seed), so the worker renders them without
    sampling again; how many were linked."""
    import json

    from studyapp.stimuli.sources import sampled_path

    def clip_key(stimulus) -> tuple:
        system = stimulus.system
        return system.checkpoint_digest, system.temperature, json.dumps(stimulus.control.control, sort_keys=True), \
            stimulus.seed

    sampled = {clip_key(s): sampled_path(s) for s in single.stimuli.exclude(system__checkpoint="")
               .filter(control__isnull=False, shown_control__isnull=True).select_related("system", "control")}
    linked = 0
    for stimulus in (study.stimuli.exclude(system__checkpoint="").filter(shown_control__isnull=True)
                     .select_related("system", "control")):
        theirs, ours = sampled.get(clip_key(stimulus)), sampled_path(stimulus)
        if theirs is not None and theirs.is_file() and not ours.exists():
            ours.parent.mkdir(parents=True, exist_ok=True)
            os.link(theirs, ours)
            linked += 1
    return linked


def ensure_researcher(var_dir: Path):
    """The demo's researcher login; the password is made once and kept under var/."""
    from django.contrib.auth.models import User

    from studyapp.researchers.accounts import grant_researcher_rights

    name = "researcher"
    secret = var_dir / "demo-researcher-password.txt"
    if not secret.exists():
        secret.write_text(secrets.token_urlsafe(12))
        secret.chmod(0o600)
    password = secret.read_text().strip()
    user, _ = User.objects.get_or_create(username=name, defaults={"is_staff": True})
    if not user.check_password(password):
        user.set_password(password)
        user.save(update_fields=["password"])
    grant_researcher_rights(user)
    return user, password


def port_is_free(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


def network_address() -> str:
    """This machine's address on its network (the interface of its default route), or
    127.0.0.1 without one. Connecting a UDP socket sends nothing."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.1", 9))  # TEST-NET-1: never routed anywhere
            return s.getsockname()[0]
        except OSError:
            return "127.0.0.1"


def participant_link(base: str, study, id_name: str) -> str:
    """An entry link of ``study`` carrying a participant id of its own: each link printed
    is one participant, whichever browser or phone opens it."""
    from django.urls import reverse

    return f"{base}{reverse('participant-enter', args=[study.key])}?{id_name}=demo-{secrets.token_hex(3)}"


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
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.server.settings")
    django.setup()
    from django.conf import settings
    from django.core.management import call_command
    from django.urls import reverse

    from generation.motion.dataset import build_dataset
    from generation.motion.dataset_options import DatasetOptions
    from studyapp.server.celery import app
    from studyapp.stimuli.natural import data_folders
    from studyapp.platforms.links import PLATFORM_PARAMETERS

    data = settings.MOTION_DATA
    missing = [folder for folder in data_folders() if not folder.is_dir()]
    if missing:
        say(f"no motion data at {', '.join(map(str, missing))}. Get the Bandai-Namco Research Motion Datasets 1 "
            "and 2 from GitHub (BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset) or use any folder of "
            "BVH files, then run:  MOTION_DATA=/path/to/folder make demo  (several folders joined with ':')")
        return 2
    try:
        port = int(env_str("DEMO_PORT", "8000"))
        train = env_bool("DEMO_TRAIN", False)
    except ValueError:
        say(f"DEMO_PORT must be a port number, got {env_str('DEMO_PORT', '8000')!r}")
        return 2
    except ImproperlyConfigured as error:
        say(str(error))
        return 2
    if not port_is_free(port):
        say(f"port {port} is in use; choose another with DEMO_PORT=8001 make demo")
        return 2
    host = env_str("DEMO_HOST", "0.0.0.0")
    address = network_address() if host == "0.0.0.0" else host

    say(f"database: {settings.DATABASES['default']['NAME']}")
    call_command("migrate", verbosity=0)
    # The app serves the collected files itself: the server does not, with DEBUG off.
    call_command("collectstatic", interactive=False, verbosity=0)
    researcher, password = ensure_researcher(Path(settings.VAR_DIR))
    try:
        say(f"building the locomotion dataset from {data}")
        dataset = build_dataset(data, DatasetOptions(**DATASET))
        say(f"dataset {dataset.fingerprint[:12]}: {len(dataset.select('train', augmented=False))} training takes, "
            f"{len(dataset.select('test'))} held out, {len(dataset.windows('train')['pose'])} training windows")
        checkpoints = ensure_models(dataset, Path(settings.VAR_DIR) / "models", train)
    except DemoStop as stop_reason:
        say(str(stop_reason))
        return 2
    except KeyboardInterrupt:
        say("stopped; make demo goes on from here")
        return 130

    worker = server = None
    try:
        say("starting one Celery worker (filesystem broker under var/broker)")
        worker = start_worker()
        wait_for_worker(app)
        count = render_gallery(data, Path(settings.MEDIA_ROOT))
        say(f"{count} natural clips rendered into {Path(settings.MEDIA_ROOT) / 'gallery'}")
        study = ensure_study(researcher, checkpoints)
        side_by_side = ensure_side_by_side_study(study)
        appropriateness = ensure_appropriateness_study(study)
        # The server answers to the address the links carry (and to this machine's own names).
        hosts = env_str("ALLOWED_HOSTS", "") or ",".join(dict.fromkeys(["localhost", "127.0.0.1", "[::1]", address]))
        server = subprocess.Popen(
            [sys.executable, "manage.py", "serve", "--noreload", f"{host}:{port}"],
            cwd=REPO, start_new_session=True, env={**os.environ, "ALLOWED_HOSTS": hosts},
        )
        base = f"http://{address}:{port}"
        if study.is_open:
            id_name = PLATFORM_PARAMETERS[study.platform][0]
            for label, each in (("single clips", study), ("side by side", side_by_side),
                                ("appropriateness", appropriateness)):
                say(f"participant link ({label}): {participant_link(base, each, id_name)}")
            say(f"   each link is one participant, in any browser or on a phone of this network; another {id_name} "
                "(or none) starts another")
        else:
            say("no stimulus could be rendered, so the study stays closed: see the stimuli page for the reasons")
        say(f"researcher:       {base}{reverse('study-list')}  (login {researcher.username} / {password})")
        say(f"gallery:          {base}/    health: {base}/health/    analysis: {base}/analysis/")
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
