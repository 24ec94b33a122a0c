"""End to end in a real browser: a study mixing every kind of system.

MoGlow (a built-in checkpoint), "OtherLab" (BVH another lab made for the exported
controls), "Toy" (a model plugin, trained here on the real data), NAT and BAD (uploaded
videos). Every clip but BAD's is rendered by the one renderer with the study's camera.
Two participants complete the study in Chromium; no page they see names a system or
its kind, every clip has the same size, and the researcher's export and report list
every system.
"""

from __future__ import annotations

import csv
import io
import re

import imageio_ffmpeg
import pytest
import torch
from django.core.files import File
from django.test import Client

from generation.control import control_from_dict
from generation.generator import Generator
from generation.motion.bvh import bvh_text, motion_to_bvh
from generation.motion.data.dataset import build_dataset
from generation.motion.data.dataset_options import DatasetOptions
from generation.train import TrainOptions, train
from tests.study_fixtures import current_clip
from studyapp.models import Participant, Stimulus, Study, System
from studyapp.stimuli.clips import plan_stimuli, render_stimulus
from studyapp.stimuli.control_export import control_id
from studyapp.stimuli.controls import add_held_out_controls
from studyapp.stimuli.submissions import add_submitted_system
from studyapp.stimuli.systems import add_checkpoint_system, add_natural_system, add_video_system
from tests.study_setup import study_files
from tests.test_model_plugin import plugin_dir  # noqa: F401 (fixture)
from tests.test_study_browser import browser, wait_for_clip_end  # noqa: F401 (fixture)

SYSTEMS = {"MoGlow", "OtherLab", "Toy", "NAT", "BAD"}
# What would tell a participant where a clip came from ("natural" is in the study's question).
GIVEAWAYS = [*SYSTEMS, "moglow", "toy", "submitted", "checkpoint", "safetensors", ".bvh", "video-upload"]


def giveaways(html: str) -> list[str]:
    """The GIVEAWAYS a page shows, not counting a word's letters inside a longer run of
    letters and digits: a random token (a CSRF token holds "toy" about once in 60 runs)
    gives nothing away."""
    def apart(word: str) -> str:
        return ((r"(?<![A-Za-z0-9])" if word[0].isalnum() else "") + re.escape(word)
                + (r"(?![A-Za-z0-9])" if word[-1].isalnum() else ""))
    return [word for word in GIVEAWAYS if re.search(apart(word), html)]


def build_study(files, tmp_path, owner) -> Study:
    study = Study.objects.create(owner=owner, title="Any model's motion", video_width=160, video_height=120,
                                 clips_per_participant=7, training_clips=1, bad_checks=1, natural_checks=1,
                                 ratings_per_stimulus=1, is_open=True, completion_code="ALL-D0NE")
    with files.good.open("rb") as upload:
        add_checkpoint_system(study, "MoGlow", File(upload, name="moglow.safetensors"))
    dataset = build_dataset(files.clips, DatasetOptions(), cache_dir=files.root / "var" / "cache", progress=False)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        train("toy", "cpu", dataset, tmp_path / "toy.safetensors", TrainOptions(steps=5, eval_every=5), progress=False)
    finally:
        torch.set_num_threads(threads)
    with (tmp_path / "toy.safetensors").open("rb") as upload:
        add_checkpoint_system(study, "Toy", File(upload, name="toy.safetensors"))
    add_natural_system(study)
    add_held_out_controls(study, 1.0)
    # The other lab's model: motion sampled away from the study, written as BVH.
    generator = Generator.load(files.good)
    submission = {f"{control_id(c)}.bvh": bvh_text(motion_to_bvh(generator.sample(
        control_from_dict(c.control), n=1, seed=7)[0])).encode() for c in study.controls.all()}
    add_submitted_system(study, "OtherLab", submission)
    with files.video.open("rb") as video:
        add_video_system(study, "BAD", [File(video, name="bad.mp4")])
    for stimulus in plan_stimuli(study)[0]:  # what the workers do, in this process
        duration = render_stimulus(stimulus)
        Stimulus.objects.filter(pk=stimulus.pk).update(status=Stimulus.Status.DONE, duration_s=duration)
    return study


def take_part(browser, live_server, study: Study, pid: str) -> list[str]:
    """Complete the study as ``pid`` (BAD rated 1, the rest 4); the HTML of every page seen."""
    context = browser.new_context()
    page = context.new_page()
    pages = []
    page.goto(f"{live_server.url}/p/{study.key}/?pid={pid}")
    pages.append(page.content())
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").wait_for()  # content() does not wait for the next page
    pages.append(page.content())
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study, platform_id=pid)
    for number, _ in enumerate(participant.training, start=1):
        page.wait_for_selector(f"text=/Practice \\w+ {number} of/")  # the page before, not yet replaced
        pages.append(page.content())
        wait_for_clip_end(page)
        page.get_by_role("button", name="3", exact=True).click()
    while (assignment := current_clip(participant)) is not None:
        # Its own token, not #clip: the page before (practice's too) has a #clip.
        page.wait_for_selector(f"input[name=assignment][value='{assignment.token}']", state="attached")
        pages.append(page.content())
        wait_for_clip_end(page)
        page.get_by_role("button", name="1" if assignment.stimulus.system.role == System.Role.BAD else "4",
                         exact=True).click()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{assignment.token}')")
    page.wait_for_load_state()  # the last page has arrived, but may not be all there yet
    pages.append(page.content())
    context.close()
    return pages


def video_size(path) -> tuple[int, int]:
    frames = imageio_ffmpeg.read_frames(str(path))
    try:
        return tuple(next(frames)["size"])
    finally:
        frames.close()


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_a_study_of_every_kind_of_system_is_completed_and_every_system_is_exported_and_reported(
        browser, live_server, plugin_dir, motion_data, settings, tmp_path, tmp_path_factory, django_user_model):
    files = study_files(motion_data, tmp_path_factory.getbasetemp())
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    settings.VAR_DIR, settings.MOTION_DATA = files.root / "var", files.clips
    owner = django_user_model.objects.create_user("researcher", password="pw-for-tests")
    study = build_study(files, tmp_path, owner)
    stimuli = list(study.stimuli.select_related("system"))
    assert {s.system.name for s in stimuli} == SYSTEMS and {s.status for s in stimuli} == {"done"}
    assert {video_size(s.video_path()) for s in stimuli} == {(160, 120)}

    seen = take_part(browser, live_server, study, "p-1") + take_part(browser, live_server, study, "p-2")
    assert "ALL-D0NE" in seen[-1]
    for html in seen:
        assert giveaways(html) == []

    client = Client()
    client.force_login(owner)
    rows = list(csv.DictReader(io.StringIO(client.get(f"/studies/{study.pk}/ratings.csv").content.decode())))
    assert {row["system"] for row in rows} == SYSTEMS
    report = client.post(f"/studies/{study.pk}/report/")
    assert report.status_code == 302 and "/analysis/" in report["Location"]
    page = client.get(report["Location"]).content.decode()
    assert all(name in page for name in SYSTEMS - {"BAD"})  # BAD is the attention check, not compared
