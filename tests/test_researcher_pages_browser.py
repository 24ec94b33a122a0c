"""Every researcher page in a real browser (headless Debian Chromium), on a desktop
(1366×768) and a phone (390×844): nothing is wider than the screen, so no page needs
sideways scrolling. With $SHOTS_DIR set, each page is also saved there as a PNG, to be
looked at."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import pytest
from django.test import Client
from django.urls import reverse

from generation.control import preset_path
from generation.motion.dataset_options import DatasetOptions
from studyapp.models import Assignment, Participant, Question, Rating
from tests.study_fixtures import make_study
from tests.test_study_browser import PASSWORD, browser  # noqa: F401 (fixture)

pytestmark = pytest.mark.slow

DESKTOP = {"viewport": {"width": 1366, "height": 768}}
PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}
SHOTS = os.environ.get("SHOTS_DIR")


def rated_study():
    """A study with questions and a few participants' ratings, so that every table has rows."""
    study = make_study(controls=2, ratings_per_stimulus=2, title="Naturalness of generated locomotion, held-out paths")
    study.owner.set_password(PASSWORD)
    study.owner.save()
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="vision",
                            text="Do you have normal or corrected-to-normal vision?", choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="comments", text="Any comments?",
                            kind=Question.Kind.TEXT, required=False)
    level = {"BAD": 1, "RNN": 2, "MoGlow": 3, "NAT": 4}
    for k in range(4):  # four participants rate every clip
        participant = Participant.objects.create(study=study, platform_id=f"6543a1b2c3d4e5f6{k:08d}")
        for i, stimulus in enumerate(study.stimuli.select_related("system").order_by("pk")):
            assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=i, page=i)
            value = min(5, level[stimulus.system.name] + (i + k) % 2)
            Rating.objects.create(assignment=assignment, value=value, client_answered_s=5.0, played_until_s=4.0)
    return study


def researcher_urls(study) -> dict[str, str]:
    system, control = study.systems.get(name="RNN"), study.controls.first()
    per_study = ("study-edit", "study-systems", "study-controls", "study-stimuli", "study-questions", "study-monitor",
                 "study-participants", "study-plan")
    return {
        "study-list": reverse("study-list"), "study-create": reverse("study-create"),
        **{name: reverse(name, args=[study.pk]) for name in per_study},
        "study-preview": reverse("study-preview-page", args=[study.pk, 4]),
        "edit-system": reverse("study-item-edit", args=[study.pk, "systems", system.pk]),
        "edit-control": reverse("study-item-edit", args=[study.pk, "controls", control.pk]),
        "remove-system": reverse("study-remove", args=[study.pk, "systems", system.pk]),
        "study-delete": reverse("study-delete", args=[study.pk]),
        "edit-question": reverse("study-question-edit", args=[study.pk, study.questions.first().pk]),
        "analysis": reverse("analysis"), "gallery": reverse("gallery"), "health": reverse("health"),
    }


def log_in(context, live_server, study):
    page = context.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    page.fill("input[name=username]", study.owner.username)
    page.fill("input[name=password]", PASSWORD)
    page.click("input[type=submit]")
    return page


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", ["desktop", "phone"])
def test_every_researcher_page_fits_the_screen(browser, live_server, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = rated_study()
    context = browser.new_context(**(PHONE if device == "phone" else DESKTOP))
    page = log_in(context, live_server, study)
    report = page.request.post(f"{live_server.url}{reverse('study-report', args=[study.pk])}", headers={
        "X-CSRFToken": next(c["value"] for c in context.cookies() if c["name"] == "csrftoken"),
        "Referer": live_server.url}, max_redirects=0)
    assert report.status == 302, report.text()
    missing = []  # no page asks for a file that is not there (the icon included); the test's clips have no videos
    page.on("response", lambda r: missing.append(r.url) if r.status == 404 and "/media/" not in r.url else None)
    too_wide = {}
    for name, url in {**researcher_urls(study), "report": report.headers["location"]}.items():
        response = page.goto(f"{live_server.url}{url}")
        assert response.status == 200, name
        if SHOTS:
            Path(SHOTS).mkdir(parents=True, exist_ok=True)
            page.screenshot(path=f"{SHOTS}/{name}-{device}.png", full_page=True)
        width = page.evaluate("document.documentElement.scrollWidth")
        if width > page.viewport_size["width"]:
            too_wide[name] = width
        # each table fits without scrolling (the participants' "Finished" column at 1366 pixels too)
        if name in ("study-monitor", "report", "study-participants") and device == "desktop":
            for index, box in enumerate(page.locator(".table-scroll").all()):
                if box.evaluate("box => box.scrollWidth > box.clientWidth"):
                    too_wide[f"{name}: table {index + 1}"] = box.evaluate("box => [box.scrollWidth, box.clientWidth]")
    context.close()
    assert too_wide == {} and missing == []
    icon = Client().get("/favicon.ico")
    assert icon.status_code == 301 and icon["Location"] == "/static/studyapp/favicon.svg"


def path_study_with_a_checkpoint_system():
    """make_study with MoGlow as a checkpoint system (its dataset options are what submissions are checked by)."""
    study = rated_study()
    study.systems.filter(name="MoGlow").update(checkpoint="m.safetensors", kind="moglow", metadata={
        "dataset_options": DatasetOptions().to_dict()})
    for control in study.controls.all():
        path = preset_path("walk-straight")
        control.control, control.seconds = {**path.to_dict(), "name": control.name}, path.n_frames / path.fps
        control.save()
    return study


@pytest.mark.django_db(transaction=True)
def test_the_settings_show_what_the_chosen_design_reads_as_it_changes(browser, live_server):
    study = make_study()
    study.owner.set_password(PASSWORD)
    study.owner.save()
    context = browser.new_context(**DESKTOP)
    page = log_in(context, live_server, study)
    page.goto(f"{live_server.url}{reverse('study-edit', args=[study.pk])}")

    def visible(label: str) -> bool:
        return page.get_by_label(label, exact=True).is_visible()

    assert visible("Clips per participant") and visible("Lowest rating") and not visible("Degrees of preference")
    page.select_option("select[name=design]", "pairwise")
    assert visible("Degrees of preference") and visible("Natural clip shown as a reference (ABX)")
    assert not visible("Lowest rating") and not visible("Clips per participant") and not visible(
        "Exclude who rates a BAD clip at or above")
    page.get_by_label("Natural clip shown as a reference (ABX)").check()
    page.select_option("select[name=design]", "side-by-side")  # the ABX switch hides, and is sent as off
    assert not visible("Natural clip shown as a reference (ABX)") and visible("Pages per participant")
    page.get_by_role("button", name="Save").click()
    page.wait_for_url(f"**{reverse('study-systems', args=[study.pk])}")
    study.refresh_from_db()
    assert (study.design, study.abx, study.scale_min, study.scale_max) == ("side-by-side", False, 0, 100)
    context.close()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", ["desktop", "phone"])
def test_an_upload_shows_its_progress_and_a_refusal_lists_its_problems_at_the_top(browser, live_server, tmp_path,
                                                                                 device):
    study = path_study_with_a_checkpoint_system()
    upload = tmp_path / "other-lab.zip"
    with zipfile.ZipFile(upload, "w") as archive:
        archive.writestr("walk.bvh", "HIERARCHY\n")
        archive.writestr("padding.txt", os.urandom(2_000_000))  # big enough to be sent in several parts
    context = browser.new_context(**(PHONE if device == "phone" else DESKTOP))
    page = log_in(context, live_server, study)
    page.goto(f"{live_server.url}{reverse('study-systems', args=[study.pk])}")
    # What the form shows while it sends, recorded as it changes (the answer then replaces the page).
    page.evaluate("""() => {
        window.seen = [];
        const form = document.querySelector("input[name=action][value=motion]").form;
        const bar = form.querySelector("progress"), status = form.querySelector(".upload-status");
        const note = () => window.seen.push([status.textContent, bar.hidden, bar.value, bar.max,
                                             form.querySelector("button[type=submit]").disabled]);
        new MutationObserver(note).observe(form, {subtree: true, childList: true, characterData: true,
                                                  attributes: true});
    }""")
    form = page.locator("form", has=page.locator("input[name=action][value=motion]"))
    form.get_by_label("Name").fill("Other lab")
    form.locator("input[type=file]").set_input_files(str(upload))
    form.get_by_role("button", name="Upload motion").click()
    page.wait_for_selector("#refused")
    seen = page.evaluate("window.seen")
    sent = [state for state in seen if state[0] == "Sent: the server is checking the file…"]
    assert sent and all(not hidden and value == total > 2_000_000 and disabled for _, hidden, value, total, disabled in sent)
    problems = page.locator("#refused li").all_inner_texts()  # one a line
    assert problems[1:4] == ["control-0: no file: refused: no file named control-0.bvh or control-0_NN.bvh",
                             "control-1: no file: refused: no file named control-1.bvh or control-1_NN.bvh",
                             "named after no control, left out: walk.bvh"]
    assert page.locator("#refused strong").inner_text() == "the submitted motion was not registered"
    refused_at = page.locator("#refused").bounding_box()["y"]
    assert refused_at < page.get_by_role("heading", name="Systems").bounding_box()["y"] + 200  # at the top
    assert page.evaluate("document.documentElement.scrollWidth") <= page.viewport_size["width"]
    context.close()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", ["desktop", "phone"])
def test_the_monitor_opens_on_the_newest_ratings_with_a_jump_to_each_part(browser, live_server, settings, tmp_path,
                                                                         device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = rated_study()
    context = browser.new_context(**(PHONE if device == "phone" else DESKTOP))
    page = log_in(context, live_server, study)
    page.goto(f"{live_server.url}{reverse('study-monitor', args=[study.pk])}")
    links = page.locator("nav.toc a")
    targets = [href.lstrip("#") for href in links.evaluate_all("(links) => links.map((a) => a.getAttribute('href'))")]
    parts = page.eval_on_selector_all("main section[id], main h2[id]", "parts => parts.map((p) => p.id)")
    assert targets == parts and targets[0] == "ratings"  # every part, in the page's order, the live numbers first
    assert {"entry", "rules-section", "data"} <= set(targets) and len(targets) >= 6
    for link, target in ((links.last, "data"), (links.nth(2), targets[2])):
        link.click()
        page.wait_for_function(f"() => Math.abs(document.getElementById('{target}').getBoundingClientRect().top) < 80"
                               " || innerHeight + scrollY >= document.documentElement.scrollHeight - 1")
        box = page.locator(f"#{target}").bounding_box()
        assert 0 <= box["y"] < page.viewport_size["height"], target  # the part is on the screen
    context.close()
