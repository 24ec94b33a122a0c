"""Model plugins: an installed package adds a model kind through the entry-point group
``motion_study.models``; its checkpoints train, upload and render like built-in ones.

The example plugin (examples/toy-motion-model) is installed for these tests with
``pip install --no-deps --no-build-isolation --target DIR``, DIR put on ``sys.path`` here
and on the worker's PYTHONPATH: the shared environment is left as it was.
"""

from __future__ import annotations

import importlib
import shutil
import socket
import sqlite3
import subprocess
import sys
import uuid
import warnings
from pathlib import Path

import pytest
import torch

from generation import registry
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.train import TrainOptions, train
from tests.study_setup import study_files
from tests.test_celery_roundtrip import clean_env, require_redis

REPO = Path(__file__).resolve().parents[1]
PLUGIN = REPO / "examples" / "toy-motion-model"


@pytest.fixture(scope="module")
def plugin_dir(tmp_path_factory) -> Path:
    """The example plugin installed into a folder of its own, on sys.path, its kind registered."""
    target = tmp_path_factory.mktemp("plugin-site")
    source = tmp_path_factory.mktemp("plugin-source") / PLUGIN.name  # setuptools builds in the tree: not in the repo's
    shutil.copytree(PLUGIN, source, ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--no-index", "--target", str(target), str(source)], check=True, capture_output=True, timeout=300)
    sys.path.insert(0, str(target))
    importlib.invalidate_caches()
    try:
        assert registry.load_plugins() == ["toy"]
        yield target
    finally:
        registry.MODELS.pop("toy", None)
        sys.path.remove(str(target))


def test_an_installed_plugin_adds_its_kind_with_its_class_and_presets(plugin_dir):
    entry = registry.model_kind("toy")
    assert (entry.title, entry.control) == ("Toy MLP", registry.PATH)
    assert registry.model_class("toy").__module__ == "toy_motion_model.model"
    assert registry.preset("toy", "cpu").hidden == 64 and registry.training_knobs("toy", "cpu")["batch_size"] == 32


def test_a_plugin_that_does_not_load_or_takes_a_built_in_name_is_left_out_with_the_reason(tmp_path):
    for name, value in (("broken", "no_such_module:KIND"), ("moglow", "no_such_module:KIND")):
        info = tmp_path / f"{name}_plugin-0.1.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}-plugin\nVersion: 0.1\n")
        (info / "entry_points.txt").write_text(f"[motion_study.models]\n{name} = {value}\n")
    sys.path.insert(0, str(tmp_path))
    importlib.invalidate_caches()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            added = registry.load_plugins()
    finally:
        sys.path.remove(str(tmp_path))
    assert "broken" not in added and "moglow" not in added
    messages = sorted(str(w.message) for w in caught)
    assert "model plugin 'broken' (no_such_module:KIND) is left out: it does not load (ModuleNotFoundError" in messages[0]
    assert "model plugin 'moglow' (no_such_module:KIND) is left out: 'moglow' is a built-in kind" in messages[1]
    assert registry.MODELS["moglow"].target == "generation.models.moglow:MoGlow" and "broken" not in registry.MODELS


RESEARCHER = """
import io, sys
import django
django.setup()
from django.core.management import call_command
from studyapp.models import System
checkpoint = sys.argv[1]
call_command("migrate", interactive=False, verbosity=0)
call_command("createsuperuser", interactive=False, username="researcher", email="r@example.org", verbosity=0)
out = io.StringIO()
call_command("create_study", "researcher", "A lab's own model", "--size", "160", "120", stdout=out)
study = out.getvalue().strip()
call_command("add_system", study, "Toy", checkpoint, stdout=io.StringIO())
call_command("add_controls", study, "--held-out", "1", "--preset", "walk-circle", stdout=io.StringIO())
call_command("generate_stimuli", study, "--wait", "--timeout", "180")
print(System.objects.get(name="Toy").kind, System.objects.get(name="Toy").metadata["preset"])
"""


@pytest.mark.redis
@pytest.mark.slow
def test_a_plugin_model_trained_on_real_data_is_uploaded_and_a_worker_renders_its_clips(
        plugin_dir, motion_data, tmp_path, tmp_path_factory):
    redis_url = require_redis()
    files = study_files(motion_data, tmp_path_factory.getbasetemp())
    dataset = build_dataset(files.clips, DatasetOptions(), cache_dir=files.root / "var" / "cache", progress=False)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        meta = train("toy", "cpu", dataset, tmp_path / "toy.safetensors", TrainOptions(steps=5, eval_every=5),
                     progress=False)
    finally:
        torch.set_num_threads(threads)
    checkpoint = tmp_path / "toy.safetensors"
    assert (meta.kind, meta.step) == ("toy", 5) and checkpoint.is_file()

    var = tmp_path / "var"
    run = uuid.uuid4().hex[:8]
    env = clean_env(STUDYAPP_VAR_DIR=str(var), CELERY_BROKER_URL=redis_url, CELERY_RESULT_BACKEND=redis_url,
                    CELERY_QUEUE=f"plugin-{run}", MOTION_DATA=str(files.clips), PYTHONPATH=str(plugin_dir),
                    DJANGO_SUPERUSER_PASSWORD="pw-for-tests", OMP_NUM_THREADS="1")
    log = tmp_path / "worker.log"
    worker = subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool=solo", "--hostname",
         f"plugin-{run}@{socket.gethostname()}", "--loglevel=info", "--without-mingle", "--without-gossip"],
        cwd=REPO, env=env, stdout=log.open("wb"), stderr=subprocess.STDOUT, start_new_session=True)
    try:
        researcher = subprocess.run([sys.executable, "-c", RESEARCHER, str(checkpoint)], cwd=REPO, env=env,
                                    capture_output=True, text=True, timeout=300)
    finally:
        worker.terminate()
        worker.wait(timeout=30)
    worker_log = log.read_text(errors="replace")
    assert researcher.returncode == 0, f"{researcher.stderr[-2000:]}\nworker:\n{worker_log[-2000:]}"
    assert researcher.stdout.split()[-2:] == ["toy", "cpu"]  # its kind, and its preset recognised
    with sqlite3.connect(var / "db.sqlite3") as db:
        rows = db.execute("SELECT status, duration_s, token FROM studyapp_stimulus").fetchall()
    assert len(rows) >= 2 and {status for status, _, _ in rows} == {"done"}
    assert all((var / "media" / "stimuli" / f"{token}.mp4").stat().st_size > 1000 for _, _, token in rows)
    assert "Task studyapp.tasks.sample_stimuli[" in worker_log
