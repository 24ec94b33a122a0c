"""Side-by-side and pairwise studies end to end in a real browser (headless Chromium).

For each design (and pairwise's ABX variant): a careful participant on a phone and one on a desktop (every clip
played to its end, the instructed check followed), one who fails the checks (NAT rated
low or BAD preferred, the instructed check ignored) and one who tries to answer before
playing (the buttons stay disabled; forcing the form sends an answer the server refuses
as too soon, and counts). On the phone the clips are shown one at a time, picked by their
tabs; on the desktop side by side. Practice is the design's own page, played and answered the
same way. The export, read back by the analysis, must hold what each one did.
"""

from __future__ import annotations

import io

import pytest

from analysis.ratings.schema import read_ratings
from studyapp.models import Participant, Rating, Study, System
from studyapp.researchers.results.export import ratings_csv
from tests.study_fixtures import current_page, make_study
from tests.test_study_browser import browser, clip_video  # noqa: F401 (fixtures)

CLIP_SECONDS = 1.0
PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}
DESKTOP = {"viewport": {"width": 1280, "height": 900}}


def video(slot: int) -> str:
    return f"document.querySelector('video[data-slot=\"{slot}\"]')"


def show_clip(page, slot) -> None:
    """Bring clip ``slot`` on screen: a phone shows one clip at a time, picked by its tab."""
    tab = page.locator(f'.clip-tabs [data-tab="{slot}"]')
    if tab.is_visible():
        tab.click()


def play_every_clip(page) -> None:
    """Play each clip on the page (ABX's reference X too) to its end, one after the other."""
    for slot in page.eval_on_selector_all("video[data-slot]", "videos => videos.map((v) => v.dataset.slot)"):
        show_clip(page, slot)
        page.locator(f'button[data-play="{slot}"]').click()
        page.wait_for_function(f"() => {video(slot)}.ended", timeout=20_000)


def one_plays_at_a_time(page) -> bool:
    """Start A, then B: A is paused."""
    page.locator('button[data-play="1"]').click()
    page.wait_for_function(f"() => !{video(1)}.paused")
    show_clip(page, 2)
    page.locator('button[data-play="2"]').click()
    page.wait_for_function(f"() => !{video(2)}.paused")
    return page.evaluate(f"{video(1)}.paused")


def set_slider(page, slot: int, value: int) -> None:
    page.locator(f"#value-{slot}").evaluate(
        "(slider, value) => { slider.value = value; slider.dispatchEvent(new Event('input')); }", value)


def careful_value(study: Study, clip) -> int:
    if clip.expected == "max":
        return study.scale_max
    return {System.Role.BAD: 5, System.Role.NATURAL: 90}.get(clip.stimulus.system.role, 60)


def careless_value(study: Study, clip) -> int:
    return 10 if clip.stimulus.system.role == System.Role.NATURAL else 50  # NAT low; the instruction ignored


def careful_choice(clips) -> str:
    if clips[0].expected:
        return clips[0].expected
    bad = [c.stimulus.system.role == System.Role.BAD for c in clips]
    return "right" if bad[0] else "left"


def careless_choice(clips) -> str:
    if clips[0].expected:
        return "right" if clips[0].expected == "left" else "left"
    bad = [c.stimulus.system.role == System.Role.BAD for c in clips]
    return "left" if bad[0] else "right"  # BAD preferred where there is one


def force_the_buttons(page) -> None:
    """Unlock the page's buttons, as a participant editing the page could."""
    page.evaluate("document.querySelectorAll('#page-form button').forEach((b) => { b.disabled = false; })")


def answer_page(page, study: Study, clips, careful: bool, forced: bool = False) -> None:
    """Answer the page of ``clips`` (none: a practice page, answered anyhow); ``forced``: with its buttons unlocked."""
    if study.design == "side-by-side":
        for clip in clips:
            set_slider(page, clip.slot, (careful_value if careful else careless_value)(study, clip))
        if not clips:  # practice: each slider moved too, as the study asks
            for slot in page.eval_on_selector_all(".clips video[data-slot]", "videos => videos.map((v) => v.dataset.slot)"):
                set_slider(page, int(slot), 60)
        if forced:  # after the sliders, whose moves lock the button again until every clip has played
            force_the_buttons(page)
        page.get_by_role("button", name="Submit ratings").click()
        return
    choice = (careful_choice if careful else careless_choice)(clips) if clips else "left"
    verb = "closer" if study.abx else "better"
    page.get_by_role("button", name=f"{'A' if choice == 'left' else 'B'} is {verb}").click()  # the choice first
    page.get_by_role("button", name="slightly", exact=True).click()  # then how strong: this sends the answer


def take_part(browser, live_server, study: Study, pid: str, screen: dict, careful: bool = True,
              hasty: bool = False) -> str:
    """Go through the study as ``pid``; returns the final page's text."""
    context = browser.new_context(**screen)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study, platform_id=pid)
    while Participant.objects.get(pk=participant.pk).training_done < len(participant.training):
        page.wait_for_selector("text=(not recorded)")
        heading = page.inner_text("p.meta")
        play_every_clip(page)
        answer_page(page, study, [], careful=True)  # not recorded
        page.wait_for_function(f"() => !document.body.innerText.includes({heading!r})")
    first = True
    while clips := current_page(participant):
        page.wait_for_selector("video[data-slot]")
        assert page.eval_on_selector_all("#page-form button[type=submit]",  # nothing played yet
                                         "buttons => buttons.every((b) => b.disabled)")
        if first:
            assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")  # no sideways scroll
            if screen is PHONE:  # one clip at a time, the others a tab away
                assert page.locator('video[data-slot="1"]').is_visible()
                assert not page.locator('video[data-slot="2"]').is_visible()
            else:  # side by side
                boxes = [page.locator(f'video[data-slot="{slot}"]').bounding_box() for slot in (1, 2)]
                assert boxes[1]["x"] >= boxes[0]["x"] + boxes[0]["width"] and boxes[1]["y"] == boxes[0]["y"]
            assert one_plays_at_a_time(page)
        answered = False
        if hasty and first:
            force_the_buttons(page)
            answer_page(page, study, clips, careful, forced=True)
            # Sooner than the clips last by the server's clock: refused. Later (a slow
            # machine), but with no clip seen to its end: taken, and flagged early.
            page.wait_for_function(f"() => document.body.innerText.includes('Please watch every clip') "
                                   f"|| !document.body.innerHTML.includes('{clips[0].token}')")
            answered = "Please watch every clip" not in page.inner_text("body")
            if not answered:
                with page.expect_navigation():  # the page left has video[data-slot] too; its script must run
                    page.get_by_role("link", name="Back to the study").click()  # to the page, still to answer
                page.wait_for_selector("video[data-slot]")
        if not answered:
            play_every_clip(page)
            answer_page(page, study, clips, careful)
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{clips[0].token}')")
        first = False
    page.wait_for_load_state()  # the last page has arrived, but may not be all there yet
    text = page.inner_text("body")
    context.close()
    return text


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("design, fields", [
    ("side-by-side", {"scale_min": 0, "scale_max": 100, "pages_per_participant": 2}),
    ("pairwise", {"pages_per_participant": 3, "preference_strengths": 3}),
    ("pairwise", {"pages_per_participant": 3, "preference_strengths": 3, "abx": True}),
])
def test_careful_careless_and_hasty_participants_in_a_browser(browser, live_server, clip_video, settings, tmp_path,
                                                              design, fields):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, training_clips=1, bad_checks=1,
                       instructed_checks=1, ratings_per_stimulus=10, design=design, **fields)

    for pid, screen in (("careful-phone", PHONE), ("careful-desktop", DESKTOP)):
        assert study.completion_code in take_part(browser, live_server, study, pid, screen)
    take_part(browser, live_server, study, "careless", DESKTOP, careful=False)
    take_part(browser, live_server, study, "hasty", DESKTOP, hasty=True)

    people = {p.platform_id: p for p in Participant.objects.filter(study=study)}
    assert all(p.finished_at is not None for p in people.values())
    assert {pid: (p.excluded, p.failed_checks) for pid, p in people.items()} == {
        "careful-phone": (False, 0), "careful-desktop": (False, 0), "careless": (True, 1), "hasty": (False, 0)}
    assert people["careless"].exclusion_reason == ("rated a NAT clip low" if design == "side-by-side"
                                                   else "preferred a BAD clip")
    early = Rating.objects.filter(answered_before_end=True)
    assert {r.assignment.participant.platform_id for r in early} <= {"hasty"}
    # The forced answer, refused or flagged: one page.
    assert sum(p.refused_early for p in people.values()) + len({r.assignment.page for r in early}) == 1
    assert people["hasty"].refused_early + early.count() >= 1

    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert set(table["design"]) == {design}
    instructed = Rating.objects.exclude(assignment__expected="").count()
    assert instructed > 0 and len(table) == Rating.objects.count() - instructed  # dictated answers left out
