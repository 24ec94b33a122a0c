"""Shared fixtures: where the real motion capture lives."""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

import pytest

from generation.motion.clip_files import motion_folders
from studyapp.server.gc_tuning import freeze_start_up
from tests.lab_rigs import LAB_RIGS, write_lab_folder

REPO = Path(__file__).resolve().parents[1]
# MOTION_DATA may name several folders joined with ":" (as the demo reads it); the tests
# are written on the first, Bandai-Namco dataset 1.
MOTION_DATA = motion_folders(os.environ.get("MOTION_DATA", REPO.parent / "shared" / "data" / "bandai-namco-1"))[0].resolve()
MOTION_DATA_2 = Path(os.environ.get(
    "MOTION_DATA_2", REPO.parent / "shared" / "data" / "bandai-namco-2-locomotion")).resolve()


def _real_data(folder: Path, variable: str) -> Path:
    if not (folder / "data").is_dir():
        if os.environ.get("CI"):
            pytest.fail(f"real motion data not found at {folder}; set {variable}")
        pytest.skip(f"real motion data not found at {folder}; set {variable}")
    return folder


@pytest.fixture(scope="session")
def motion_data() -> Path:
    """The real BVH folder (the Bandai-Namco data); tests that need it fail in CI without it."""
    return _real_data(MOTION_DATA, "MOTION_DATA")


@pytest.fixture(scope="session")
def motion_data_2() -> Path:
    """Bandai-Namco dataset-2's locomotion (another BVH formatting, data the project was
    not written on); tests that need it fail in CI without it."""
    return _real_data(MOTION_DATA_2, "MOTION_DATA_2")


@pytest.fixture(scope="session")
def demo_dataset_cache(pytestconfig, motion_data, motion_data_2) -> Path:
    """A dataset cache folder holding the demo's dataset (both Bandai-Namco folders,
    prepared as ``make demo`` prepares them), built once per run: in pytest's cache
    folder, which the test processes share, the first to need it building it while the
    others wait (it takes 40 s here; reading it back 3 s)."""
    from generation.motion.dataset import build_dataset
    from generation.motion.dataset_options import DatasetOptions
    from studyapp import demo

    cache = pytestconfig.cache.mkdir("motion-dataset")
    with (cache / "demo-dataset.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        build_dataset(os.pathsep.join(map(str, (motion_data, motion_data_2))), DatasetOptions(**demo.DATASET),
                      cache_dir=cache, progress=False)
    return cache


@pytest.fixture(scope="session")
def clip_path(motion_data):
    """Path of a named clip, e.g. clip_path('walk-left_normal_001')."""
    return lambda name: motion_data / "data" / f"dataset-1_{name}.bvh"


@pytest.fixture(scope="session")
def lab_rigs(motion_data_2, tmp_path_factory) -> dict[str, Path]:
    """Other labs' rigs and files (``tests/lab_rigs.py``: CMU's in CMU units and in metres,
    ACCAD's), each a folder of three real walks, by the rig's name."""
    return {name: write_lab_folder(motion_data_2, rig, tmp_path_factory.mktemp(name)) for name, rig in LAB_RIGS.items()}


@pytest.fixture(autouse=True)
def fast_password_hashing():
    """Passwords made in tests are hashed with one round of MD5: the real hasher's million
    rounds cost 0.7 s a password on this machine, and no test measures them. Hashes made
    by the real hasher (in a subprocess's createsuperuser) still check. (Not through the
    ``settings`` fixture: some tests have a parameter of that name.)"""
    from django.conf import settings
    from django.test import override_settings

    hashers = ["django.contrib.auth.hashers.MD5PasswordHasher", *(h for h in settings.PASSWORD_HASHERS if "MD5" not in h)]
    with override_settings(PASSWORD_HASHERS=hashers):
        yield


def pytest_collection_finish(session: pytest.Session) -> None:
    """What collecting the tests made lives to the end: out of the collector's sight. (The
    collector collects less often once studyapp is imported: studyapp.server.gc_tuning.
    Collecting the suite takes 15 s of CPU a process instead of 27, the web fuzzing about
    70 s instead of 80.)"""
    freeze_start_up()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The modules holding a slow test first, the others after them, each in file order.
    make test's processes take whole modules in this order (pytest-xdist's ``--dist
    loadfile --no-loadscope-reorder``), so the long modules start while short ones can
    still run beside them, and the run does not end on one long module alone. Most of
    the long ones wait on a browser playing clips in real time more than they compute."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)


def pytest_configure(config: pytest.Config) -> None:
    """One thread of numerical work per test process where make test runs at least as many
    processes as there are cores: the processes already keep every core busy, and the
    tests' tensors and matrices are small, so a second thread mostly spins waiting for
    its share (the numerical modules on 3 processes here: 106 s and 193 s of CPU on one
    thread each, 173 s and 331 s with the default two). The servers and workers the tests
    start inherit it through the environment."""
    workers = getattr(config, "workerinput", {}).get("workercount", 1)
    if workers < (os.cpu_count() or 1):
        return
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = "1"
    import torch
    from threadpoolctl import threadpool_limits

    torch.set_num_threads(1)
    threadpool_limits(1)
