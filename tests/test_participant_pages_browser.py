"""The participant's pages in a real browser (headless Debian Chromium), on a desktop
(1366×768) and a phone (390×844): what the multi-clip pages' script does (the slider's
number, the sliders that must be moved, the played marks, one clip at a time on a phone),
what each page shows where (above the fold, on one line, no dark edge on a clip), and
`every_page`, the walk through every page of a design that checks nothing on it is wider
than the screen (tests/test_accessibility.py takes it for every design on both screens,
checking each page with axe-core too). With $SHOTS_DIR set, each page is also saved there
as a PNG, to be looked at."""

from __future__ import annotations

import io
import os
import time
from pathlib import Path

import numpy as np
import pytest
from django.utils import timezone
from PIL import Image

from studyapp.models import Assignment, ControlSignal, Participant, Rating, Stimulus, Study, System
from tests.study_fixtures import make_study
from tests.test_study_browser import browser, clip_video  # noqa: F401 (fixtures)

pytestmark = pytest.mark.slow

CLIP_SECONDS = 1.0
DESKTOP = {"viewport": {"width": 1366, "height": 768}}
PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}
SCREENS = {"desktop": DESKTOP, "phone": PHONE}
SHOTS = os.environ.get("SHOTS_DIR")
SIDE_BY_SIDE = {"design": "side-by-side", "scale_min": 0, "scale_max": 100, "pages_per_participant": 2}


def shoot(page, name: str) -> None:
    if SHOTS:
        Path(SHOTS).mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(Path(SHOTS) / f"{name}.png"), full_page=True)


def enter(browser, live_server, study: Study, screen: dict, pid: str = "p1"):
    """A participant's browser tab on the study's first page."""
    page = browser.new_context(**screen).new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    return page


def skip_to_ratings(page, study: Study, pid: str = "p1") -> Participant:
    """Past consent, instructions and practice (as if passed), on the first rated page."""
    participant = Participant.objects.get(study=study, platform_id=pid)
    now = timezone.now()
    Participant.objects.filter(pk=participant.pk).update(device_checked_at=now, consented_at=now, screened_at=now,
                                                         instructed_at=now, training_done=len(participant.training))
    page.reload()
    page.wait_for_selector("video:not([data-upcoming])")  # not the next page's, loading hidden
    return participant


def visible_clips(page) -> list[str]:
    return page.eval_on_selector_all(".clips > .clip", "sections => sections.filter((s) => s.offsetParent !== null)"
                                                       ".map((s) => s.id)")


def show_clip(page, slot) -> None:
    """Bring clip ``slot`` on screen: its tab on a phone (nothing to do on a desktop)."""
    tab = page.locator(f'.clip-tabs [data-tab="{slot}"]')
    if tab.is_visible():
        tab.click()


def play_to_end(page, slot) -> None:
    show_clip(page, slot)
    page.locator(f'button[data-play="{slot}"]').click()
    page.wait_for_function(f"() => document.querySelector('video[data-slot=\"{slot}\"]').ended", timeout=20_000)


def slots_on_page(page) -> list[str]:
    return page.eval_on_selector_all(".clips video[data-slot]", "videos => videos.map((v) => v.dataset.slot)")


def add_system(study: Study, name: str) -> None:
    """Another model with a finished clip of every control (a copy of an existing clip's file)."""
    system = System.objects.create(study=study, name=name, checkpoint=f"{name}.safetensors",
                                   checkpoint_digest=name * 8, kind="moglow")
    for control in ControlSignal.objects.filter(study=study):
        model = study.stimuli.filter(control=control, system__name="MoGlow").first()
        stimulus = Stimulus.objects.create(study=study, system=system, control=control, status=Stimulus.Status.DONE,
                                           content_key=f"{name}-{control.name}", duration_s=model.duration_s)
        if model.video_path().exists():
            stimulus.video_path().write_bytes(model.video_path().read_bytes())


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_the_sliders_number_follows_dragging_keys_and_script(browser, live_server, clip_video, settings, tmp_path,
                                                            device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, SCREENS[device])
    skip_to_ratings(page, study)
    number = page.locator('output[for="value-1"]')
    assert number.inner_text() == "50"
    slider = page.locator("#value-1")
    box = slider.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * 0.9, box["y"] + box["height"] / 2, steps=5)
    page.mouse.up()
    dragged = slider.input_value()
    assert int(dragged) > 70 and number.inner_text() == dragged
    slider.focus()
    page.keyboard.press("ArrowLeft")
    page.keyboard.press("ArrowLeft")
    assert number.inner_text() == str(int(dragged) - 2) == slider.input_value()
    slider.evaluate("(s) => { s.value = 17; s.dispatchEvent(new Event('input')); }")
    assert number.inner_text() == "17"


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_the_answer_waits_for_every_slider_to_move_and_each_played_clip_is_marked(browser, live_server, clip_video,
                                                                                 settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, {**SCREENS[device], "reduced_motion": "reduce"})  # nothing plays by itself
    participant = skip_to_ratings(page, study)
    submit = page.get_by_role("button", name="Submit ratings")
    slots = slots_on_page(page)
    for slot in slots:
        assert not page.locator(f'.clip [data-played="{slot}"]').is_visible()
        play_to_end(page, slot)
        page.locator(f'.clip [data-played="{slot}"]').wait_for()  # set by the "ended" event, a moment after .ended
        assert page.locator(f'.clip [data-played="{slot}"]').is_visible()  # "played ✓" by its clip
        if device == "phone":
            assert page.locator(f'.clip-tabs [data-played="{slot}"]').is_visible()  # and on its tab
    note = page.locator("#move-note")
    assert submit.is_disabled() and "not yet moved: clip A, B, C" in note.inner_text()
    for slot in slots[:-1]:
        show_clip(page, slot)
        page.locator(f"#value-{slot}").focus()
        page.keyboard.press("ArrowRight")
    assert submit.is_disabled() and "not yet moved: clip C" in note.inner_text()
    show_clip(page, slots[-1])
    page.locator(f"#value-{slots[-1]}").focus()
    page.keyboard.press("ArrowRight")
    page.keyboard.press("ArrowLeft")  # back to the start: still moved
    assert submit.is_enabled() and not note.is_visible()
    submit.click()
    page.wait_for_function("() => document.body.innerText.includes('Page 2 of')")
    assert sorted(Rating.objects.filter(assignment__participant=participant).values_list("value", flat=True)) == \
        [50, 51, 51]


@pytest.mark.django_db(transaction=True)
def test_a_phone_shows_one_clip_at_a_time_with_every_slider_in_the_form(browser, live_server, clip_video, settings,
                                                                       tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, PHONE)
    skip_to_ratings(page, study)
    assert visible_clips(page) == ["clip-1"]
    video = page.locator('video[data-slot="1"]').bounding_box()
    assert video["y"] + video["height"] <= 844  # the clip and its play button on the screen at once
    assert page.locator('button[data-play="1"]').bounding_box()["y"] < 844
    page.locator('.clip-tabs [data-tab="2"]').click()
    assert visible_clips(page) == ["clip-2"]
    assert page.locator('.clip-tabs [data-tab="2"]').get_attribute("aria-selected") == "true"
    assert page.evaluate("[...document.getElementById('page-form').elements].filter((e) => e.type === 'range')"
                         ".map((e) => e.name)") == ["value-1", "value-2", "value-3"]
    desktop = enter(browser, live_server, study, DESKTOP, pid="p2")
    skip_to_ratings(desktop, study, "p2")
    assert not desktop.locator(".clip-tabs").is_visible() and len(visible_clips(desktop)) == 3


@pytest.mark.django_db(transaction=True)
def test_the_single_clip_pages_hints_and_end_labels_are_above_the_fold(browser, live_server, clip_video, settings,
                                                                      tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2)
    page = enter(browser, live_server, study, DESKTOP)
    skip_to_ratings(page, study)
    for selector in ("#lock-hint", "#keys-hint", ".scale .ends"):
        box = page.locator(selector).bounding_box()
        assert box["y"] + box["height"] <= 768, selector


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("height", [768, 800])
def test_the_single_clip_page_fits_a_laptops_screen_without_scrolling(browser, live_server, clip_video, settings,
                                                                     tmp_path, height):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2)
    page = enter(browser, live_server, study, {"viewport": {"width": 1366, "height": height}})
    skip_to_ratings(page, study)
    page.evaluate("() => { const v = document.getElementById('clip'); v.pause(); v.currentTime = 0; }")
    shoot(page, f"single-1366x{height}-locked")
    assert page.is_visible("#lock-hint") and page.is_visible("#keys-hint")  # the page at its tallest
    assert page.evaluate("document.documentElement.scrollHeight") <= height
    box = page.locator("#keys-hint").bounding_box()
    assert box["y"] + box["height"] <= height


def figure_height(page, slot: str) -> int:
    """How many pixel rows of clip ``slot``'s box the character's left side (drawn red) spans, paused mid-clip."""
    page.evaluate(f"() => {{ const v = document.querySelector('video[data-slot=\"{slot}\"]'); v.pause();"
                  " v.currentTime = 0.5; }")
    page.wait_for_timeout(300)
    frame = np.asarray(Image.open(io.BytesIO(page.locator(f'video[data-slot="{slot}"]').screenshot())).convert("RGB"))
    red = (frame[..., 0] > 140) & (frame[..., 1] < 90) & (frame[..., 2] < 90)
    rows = np.flatnonzero(red.any(axis=1))
    return int(rows[-1] - rows[0] + 1) if len(rows) else 0


@pytest.mark.django_db(transaction=True)
def test_a_phones_clip_tabs_are_one_stop_of_the_tab_key_and_the_arrows_choose_among_them(
        browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, {**PHONE, "reduced_motion": "reduce"})
    skip_to_ratings(page, study)
    tabs = page.locator(".clip-tabs [data-tab]")
    chosen = lambda: page.evaluate(  # noqa: E731 (the chosen tab, the focused one, and which is in the Tab order)
        """() => [...document.querySelectorAll('.clip-tabs [data-tab]')].map((tab) =>
            `${tab.dataset.tab}:${tab.getAttribute('aria-selected')}:${tab.tabIndex}:${tab === document.activeElement}`)""")
    assert tabs.count() == 3 and page.locator(".clips > .clip[role=tabpanel]").count() == 3
    tabs.first.focus()
    assert chosen() == ["1:true:0:true", "2:false:-1:false", "3:false:-1:false"]
    for key, expected in (("ArrowRight", "2"), ("ArrowRight", "3"), ("ArrowRight", "1"), ("ArrowLeft", "3"),
                          ("Home", "1"), ("End", "3")):
        page.keyboard.press(key)
        assert [state for state in chosen() if ":true:0:true" in state] == [f"{expected}:true:0:true"], key
        assert page.locator(f"#clip-{expected}").is_visible() and len(visible_clips(page)) == 1, key
    shoot(page, "side-by-side-phone-tab-chosen-by-keyboard")


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("models", [2, 3])  # with NAT and the BAD anchor: 4 and 5 clips
def test_four_or_five_clips_in_a_row_draw_the_character_large_with_submit_on_the_screen(
        browser, live_server, clip_video, settings, tmp_path, models):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=2, **SIDE_BY_SIDE)
    if models == 3:
        add_system(study, "VAE")
    page = enter(browser, live_server, study, {"viewport": {"width": 1366, "height": 800}, "reduced_motion": "reduce"})
    skip_to_ratings(page, study)
    slots = slots_on_page(page)
    assert len(slots) == models + 2
    tallest = max(figure_height(page, slot) for slot in slots)
    shoot(page, f"side-by-side-{models + 2}-clips-1366x800")
    assert tallest >= (125 if models == 2 else 115), tallest  # 4:3 boxes of 318 / 250 px drew 92 / 73
    submit = page.get_by_role("button", name="Submit ratings").bounding_box()
    assert submit["y"] + submit["height"] <= 800 and page.evaluate(
        "document.documentElement.scrollWidth <= window.innerWidth")


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_the_clips_of_a_page_play_by_themselves_one_after_another_unless_motion_is_reduced(
        browser, live_server, clip_video, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, SCREENS[device])
    skip_to_ratings(page, study)
    slots = slots_on_page(page)
    shown = slots if device == "desktop" else slots[:1]  # a phone plays the clip on its screen only
    for slot in shown:
        page.wait_for_function(f"() => document.querySelector('video[data-slot=\"{slot}\"]').ended",
                               timeout=20_000)
    started = page.eval_on_selector_all("video[data-slot]", "videos => videos.map((v) => v.played.length > 0)")
    assert started == [slot in shown for slot in slots]
    if device == "phone":  # the next tab's clip plays when it is shown
        show_clip(page, slots[1])
        page.wait_for_function(f"() => document.querySelector('video[data-slot=\"{slots[1]}\"]').ended",
                               timeout=20_000)
    still = enter(browser, live_server, study, {**SCREENS[device], "reduced_motion": "reduce"}, pid="p2")
    skip_to_ratings(still, study, "p2")
    still.wait_for_timeout(1500)
    assert still.eval_on_selector_all("video[data-slot]", "videos => videos.map((v) => v.played.length)") == \
        [0] * len(slots)


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_a_single_clip_plays_by_itself_unless_motion_is_reduced_when_it_waits_for_its_button(
        browser, live_server, clip_video, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0)
    moving = enter(browser, live_server, study, SCREENS[device])
    skip_to_ratings(moving, study)
    moving.wait_for_function("() => document.getElementById('clip').ended", timeout=20_000)  # by itself
    assert moving.locator("#replay").inner_text() == "Play again"

    still = enter(browser, live_server, study, {**SCREENS[device], "reduced_motion": "reduce"}, pid="p2")
    skip_to_ratings(still, study, "p2")
    play = still.get_by_role("button", name="Play", exact=True)
    play.wait_for()
    # Loaded far enough to have started by itself, and still at its start, the answers locked.
    still.wait_for_function("() => document.getElementById('clip').readyState >= HTMLMediaElement.HAVE_ENOUGH_DATA",
                            timeout=20_000)
    assert still.locator("#clip").evaluate("(video) => video.paused && video.currentTime === 0")
    assert still.locator("button[name=value]").first.is_disabled()
    shoot(still, f"single-clip-reduced-motion-{device}")
    play.click()
    still.wait_for_function("() => !document.querySelector('button[name=value]').disabled", timeout=20_000)
    assert still.locator("#clip").evaluate("(video) => video.ended")  # unlocked by its end
    assert still.locator("#replay").inner_text() == "Play again"


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("reduced", [False, True], ids=["moving", "reduced-motion"])
def test_a_single_clip_waits_for_its_pages_script_however_late_it_comes(browser, live_server, clip_video, settings,
                                                                        tmp_path, reduced):
    """A clip started before the page's script arrived would go unrecorded (its start) and, on a
    short clip, end by itself where motion is reduced: the script starts it, or leaves it waiting."""
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0)
    page = enter(browser, live_server, study, {**DESKTOP, "reduced_motion": "reduce" if reduced else "no-preference"})

    def late(route) -> None:
        time.sleep(2 * CLIP_SECONDS)  # longer than the clip: one that started by itself would have ended
        route.continue_()

    page.route("**/clip-page*.js", late)
    skip_to_ratings(page, study)  # the page loaded again, its script late
    if reduced:
        page.get_by_role("button", name="Play", exact=True).wait_for()
        assert page.locator("#clip").evaluate("(video) => video.paused && video.played.length === 0")
    else:
        page.wait_for_function("() => document.getElementById('clip').ended", timeout=20_000)
        assert page.locator("input[name=started_s]").input_value() != ""


@pytest.mark.django_db(transaction=True)
def test_a_phones_clip_tabs_show_every_sliders_rating(browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, {**PHONE, "reduced_motion": "reduce"})
    skip_to_ratings(page, study)
    show_clip(page, "2")
    page.locator("#value-2").evaluate("(s) => { s.value = 83; s.dispatchEvent(new Event('input')); }")
    show_clip(page, "1")
    shoot(page, "side-by-side-phone-tabs-with-ratings")
    tabs = page.locator(".clip-tabs [data-tab]")
    assert [text.split()[:2] for text in tabs.all_inner_texts()] == [["A", "50"], ["B", "83"], ["C", "50"]]
    assert all(box["y"] + box["height"] <= 844 and box["x"] + box["width"] <= 390
               for box in (tab.bounding_box() for tab in tabs.all()))
    assert all(tab.evaluate("(t) => t.getClientRects().length === 1 && t.offsetHeight < 50") for tab in tabs.all())


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("models", [2, 3])  # with NAT and the BAD anchor: 4 and 5 clips
def test_side_by_side_end_labels_stay_on_one_line_with_four_or_five_clips(browser, live_server, clip_video, settings,
                                                                          tmp_path, models):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=2, **SIDE_BY_SIDE)
    if models == 3:
        add_system(study, "VAE")
    page = enter(browser, live_server, study, DESKTOP)
    skip_to_ratings(page, study)
    assert len(slots_on_page(page)) == models + 2
    labels = page.eval_on_selector_all(".clip .ends span", "spans => spans.map((s) => [s.getClientRects().length, "
                                                          "s.getBoundingClientRect().top])")
    assert all(lines == 1 for lines, _ in labels)  # no label broken over two lines
    tops = [top for _, top in labels]
    assert max(tops) - min(tops) < 1  # each clip's two labels on one line, every clip's at one height
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")


@pytest.mark.django_db(transaction=True)
def test_the_pairwise_question_and_its_prompt_are_two_lines(browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, design="pairwise",
                       pages_per_participant=3)
    page = enter(browser, live_server, study, DESKTOP)
    skip_to_ratings(page, study)
    question, prompt = page.locator("p.question"), page.locator("p.prompt")
    assert question.inner_text() == study.question and prompt.inner_text() == "Which clip is better?"
    assert prompt.bounding_box()["y"] >= question.bounding_box()["y"] + question.bounding_box()["height"]


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_a_graded_preference_asks_the_choice_first_then_slightly_or_clearly_all_on_the_screen(
        browser, live_server, clip_video, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, design="pairwise",
                       pages_per_participant=3, preference_strengths=2)
    page = enter(browser, live_server, study, {**SCREENS[device], "reduced_motion": "reduce"})
    participant = skip_to_ratings(page, study)
    height = SCREENS[device]["viewport"]["height"]
    answers = page.locator("#page-form button[name=answer]")
    assert answers.all_inner_texts() == ["A is better", "No preference", "B is better"]
    assert not page.locator("fieldset.strength").is_visible()  # the choice first
    for box in (answer.bounding_box() for answer in answers.all()):
        assert box["y"] + box["height"] <= height  # "B is better" on the screen, a phone's too
    play_to_end(page, "1")
    play_to_end(page, "2")
    shoot(page, f"pairwise-graded-{device}-choice")
    page.get_by_role("button", name="B is better").click()
    shoot(page, f"pairwise-graded-{device}-strength")
    strength = page.locator("fieldset.strength")
    assert strength.is_visible() and page.locator("fieldset.strength button").all_inner_texts() == [
        "slightly", "clearly"]  # the docs' and the appropriateness pages' words
    assert strength.bounding_box()["y"] > answers.first.bounding_box()["y"]  # asked after the choice, below it
    assert page.get_by_role("button", name="B is better").get_attribute("aria-pressed") == "true"
    box = page.get_by_role("button", name="clearly").bounding_box()
    assert box["y"] + box["height"] <= height  # brought on the screen
    page.get_by_role("button", name="clearly").click()
    page.wait_for_function("() => document.body.innerText.includes('Page 2 of')")
    rating = Rating.objects.get(assignment__participant=participant, assignment__slot=1)
    assert (rating.answer, rating.strength) == ("right", 2)


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("width, height, said", [(320, 0, "at least 320 pixels wide"),
                                                 (0, 400, "at least 400 pixels high"),
                                                 (320, 400, "at least 320 × 400 pixels")])
def test_the_device_check_names_only_the_sizes_the_study_sets(browser, live_server, clip_video, settings, tmp_path,
                                                             width, height, said):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, device_check=True,
                       min_screen_width=width, min_screen_height=height)
    page = enter(browser, live_server, study, PHONE)
    assert f"Your screen is {said}:" in page.locator("#check-screen").inner_text()
    small = enter(browser, live_server, study, {"viewport": {"width": 300, "height": 300}}, pid="p2")
    small.wait_for_function("() => !document.getElementById('device-problem').hidden")
    assert f"This study needs a screen {said}." in small.locator("#device-problem").inner_text()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_a_played_clip_has_no_dark_edge(browser, live_server, clip_video, settings, tmp_path, device):
    """The clip's frame covers its box to the last pixel column (the box's black shows nowhere)."""
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, **SIDE_BY_SIDE)
    page = enter(browser, live_server, study, SCREENS[device])
    skip_to_ratings(page, study)
    for slot in slots_on_page(page):
        play_to_end(page, slot)
        frame = np.asarray(Image.open(io.BytesIO(page.locator(f'video[data-slot="{slot}"]').screenshot())).convert("L"))
        inner = frame[4:-4]  # the rounded corners aside
        assert inner[:, -1].mean() > 200 and inner[:, 0].mean() > 200, (slot, inner[:, -3:].mean(axis=0))


def every_page(study: Study, page, prefix: str, pid: str = "tour", on_page=None) -> None:
    """Walk participant ``pid`` (on ``page``) through every page of ``study``, checking each
    fits the screen, passing its name to ``on_page`` (if given) and saving it as
    ``prefix-<page>``; what is not reached by answering is reached by setting the
    participant's progress as answering would."""
    def look(name: str) -> None:
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth"), name
        if on_page:
            on_page(name)
        shoot(page, f"{prefix}-{name}")

    page.wait_for_function("() => document.getElementById('device-ok') && !document.getElementById('device-ok')"
                           ".disabled", timeout=20_000)
    look("device-check")
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="I agree to take part").wait_for()
    look("consent")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("radio", name="yes").check()
    look("screening")
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").wait_for()
    assert ("scale" in page.inner_text(".task").lower()) is (study.design == "single")  # the design's own task
    look("instructions")
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("text=(not recorded)")
    look("practice")
    participant = skip_to_ratings(page, study, pid)
    if study.design == "single":  # its clip plays by itself
        page.wait_for_function("() => document.getElementById('clip').ended", timeout=20_000)
    else:
        play_to_end(page, slots_on_page(page)[0])
    if study.design == "side-by-side":
        slots = slots_on_page(page)
        page.locator(f"#value-{slots[0]}").evaluate("(s) => { s.value = 70; s.dispatchEvent(new Event('input')); }")
    look("rating")
    pages = list(participant.assignments.order_by("position"))
    check = next(a.page for a in pages if a.expected)
    answer_by_hand([a for a in pages if a.page < check])
    page.reload()
    page.wait_for_selector(".instruction")
    look("instructed-check")
    answer_by_hand([a for a in pages if a.page >= check])
    Participant.objects.filter(pk=participant.pk).update(finished_at=timezone.now())
    page.reload()
    look("survey")
    Participant.objects.filter(pk=participant.pk).update(surveyed_at=timezone.now())
    page.reload()
    look("end")
    Participant.objects.filter(pk=participant.pk).update(stopped_at=timezone.now())
    page.reload()
    look("stopped")
    Participant.objects.filter(pk=participant.pk).update(screened_out_at=timezone.now())
    page.reload()
    look("screened-out")


def answer_by_hand(assignments: list[Assignment]) -> None:
    """Store an answer for each of ``assignments`` as the page would have."""
    for assignment in assignments:
        study = assignment.participant.study
        on_scale = study.design in ("single", "side-by-side")
        Rating.objects.create(assignment=assignment, value=study.scale_min if on_scale else None,
                              answer="" if on_scale else Rating.Answer.LEFT, client_answered_s=5.0)
