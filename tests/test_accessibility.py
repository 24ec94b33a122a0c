"""Accessibility, checked by a machine in a real browser (headless Debian Chromium): axe-core
(pinned in tests/axe/, installed into var/node/ by scripts/ensure-axe.sh, which make test
runs) finds no serious or critical violation on any participant page of any design, on a
desktop (1366×800) and a phone (390×844), nor on the researcher's pages; every rating
control has a name in the browser's accessibility tree; and the whole participant path of
each design is taken with the keyboard alone, with reduced motion asked for: nothing moves on
the page, and each clip waits for its play button.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from django.urls import reverse

from studyapp.models import Participant, Question, Stimulus, Study
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.study_fixtures import make_study
from tests.test_participant_pages_browser import SIDE_BY_SIDE, every_page
from tests.test_researcher_pages_browser import log_in, rated_study, researcher_urls
from tests.test_study_browser import browser, clip_video  # noqa: F401 (fixtures)

pytestmark = pytest.mark.slow

AXE = Path(__file__).resolve().parents[1] / "var" / "node" / "node_modules" / "axe-core" / "axe.min.js"
CLIP_SECONDS = 1.0
DESKTOP = {"viewport": {"width": 1366, "height": 800}}
PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}
SCREENS = {"desktop": DESKTOP, "phone": PHONE}
BLOCKING = ("serious", "critical")
DESIGNS = {
    "single": {"clips_per_participant": 4},
    "side-by-side": SIDE_BY_SIDE,
    "pairwise": {"design": "pairwise", "pages_per_participant": 3},
    "pairwise-graded": {"design": "pairwise", "pages_per_participant": 3, "preference_strengths": 3},
    "appropriateness": {},
}
# The controls a participant answers with, on every design's rating pages.
RATING_CONTROLS = "button[name=value], input[type=range], [name=strength], button[name=answer]"


@pytest.fixture(scope="module")
def axe() -> Path:
    if not AXE.is_file():
        message = f"axe-core is not installed at {AXE}: scripts/ensure-axe.sh installs it (make test runs it)"
        pytest.fail(message) if os.environ.get("CI") else pytest.skip(message)
    return AXE


def serious_violations(page, axe: Path) -> list[str]:
    """axe-core's serious and critical violations on the page as it is now, one line each."""
    if not page.evaluate("() => typeof window.axe === 'object'"):  # a page swapped in without a reload keeps it
        page.add_script_tag(path=str(axe))
    found = page.evaluate("""async () => (await axe.run(document, {resultTypes: ["violations"]})).violations
        .map((v) => ({id: v.id, impact: v.impact, help: v.help, where: v.nodes.map((n) => n.target.join(" "))}))""")
    return [f"{v['id']} ({v['impact']}): {v['help']}: {', '.join(v['where'][:4])}"
            for v in found if v["impact"] in BLOCKING]


def accessible_names(page, selector: str) -> list[tuple[str, str]]:
    """(role, name) of each element matching ``selector`` that a screen reader is given, as
    the browser's accessibility tree gives them."""
    cdp = page.context.new_cdp_session(page)
    try:
        root = cdp.send("DOM.getDocument", {"depth": 0})["root"]["nodeId"]
        nodes = cdp.send("DOM.querySelectorAll", {"nodeId": root, "selector": selector})["nodeIds"]
        named = []
        for node in nodes:
            ax = cdp.send("Accessibility.getPartialAXTree", {"nodeId": node, "fetchRelatives": False})["nodes"][0]
            if ax.get("ignored"):  # not on screen (another clip's slider, behind its tab on a phone)
                continue
            named.append((ax.get("role", {}).get("value", ""), ax.get("name", {}).get("value", "").strip()))
        return named
    finally:
        cdp.detach()


def make_design_study(design: str, video: Path) -> Study:
    """A study of ``design`` with every page there is: device check, a screening question, a
    practice clip, an instructed check and a closing question."""
    common = {"video": video, "clip_seconds": CLIP_SECONDS, "training_clips": 1, "instructed_checks": 1,
              "ratings_per_stimulus": 10, "device_check": True, "min_screen_width": 360, "stopped_code": "ST0PPED",
              "screen_out_code": "SCR33N"}
    study = (make_appropriateness_study(**common, **DESIGNS[design]) if design == "appropriateness"
             else make_study(controls=2, **common, **DESIGNS[design]))
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="vision",
                            text="Do you have normal or corrected-to-normal vision?", choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="comments", text="Any comments?",
                            kind=Question.Kind.TEXT, required=False)
    return study


class Findings:
    """What axe-core and the name check found, by page, gathered over a walk and asserted at its end."""

    def __init__(self, axe: Path):
        self.axe, self.found = axe, {}

    def check(self, page, where: str, with_axe: bool = True) -> None:
        problems = serious_violations(page, self.axe) if with_axe else []
        if page.locator(RATING_CONTROLS).count():
            problems += [f"a {role or 'control'} without a name" for role, name in accessible_names(
                page, RATING_CONTROLS) if not name]
        if problems:
            self.found[where] = problems

    def assert_none(self) -> None:
        if self.found:
            pytest.fail("\n".join(f"{where}: {problem}" for where, problems in self.found.items()
                                   for problem in problems), pytrace=False)


def tab_to(page, target) -> None:
    """Move the focus to ``target`` with the Tab key alone (it must be in the tab order)."""
    for _ in range(60):
        if target.evaluate("(element) => element === document.activeElement"):
            return
        page.keyboard.press("Tab")
    raise AssertionError(f"Tab never reaches {target}: " + target.evaluate(
        "(element) => `${element.outerHTML} (disabled: ${element.disabled}), the focus on "
        "${document.activeElement.outerHTML.slice(0, 200)}`"))


def press(page, target, key: str = "Enter") -> None:
    tab_to(page, target)
    page.keyboard.press(key)


def page_id(page) -> str:
    return page.evaluate("() => document.querySelector('main').dataset.pageId || ''")


def show_with_the_keyboard(page, slot: str) -> None:
    """Bring clip ``slot`` on screen: on a phone, by choosing its tab with the arrow keys from the
    chosen one, the tab in the Tab order (a desktop shows every clip)."""
    tab = page.locator(f'.clip-tabs [data-tab="{slot}"]')
    if tab.is_visible():
        tab_to(page, page.locator(".clip-tabs [aria-selected=true]"))
        for _ in range(page.locator(".clip-tabs [data-tab]").count()):
            if tab.get_attribute("aria-selected") == "true":
                break
            page.keyboard.press("ArrowRight")
        assert tab.get_attribute("aria-selected") == "true"
        assert tab.evaluate("(element) => element === document.activeElement")


def answer_with_the_keyboard(page) -> None:
    """Answer the rating page on screen with Tab, arrows, Space and Enter only."""
    if page.locator("#rating-form").count():  # one clip, a scale of buttons; motion reduced, it waits for Play
        page.wait_for_function("() => document.getElementById('replay').textContent === 'Play'", timeout=20_000)
        press(page, page.locator("#replay"))
        page.wait_for_function("() => document.getElementById('clip').ended", timeout=20_000)
        press(page, page.locator("button[name=value][value='3']"))
        return
    slots = page.eval_on_selector_all(".reference video[data-slot], .clips video[data-slot]",
                                      "videos => videos.map((v) => v.dataset.slot)")
    for slot in slots:  # each started from its play button, and played to its end
        show_with_the_keyboard(page, slot)
        press(page, page.locator(f'button[data-play="{slot}"]'))
        page.wait_for_function(f"() => document.querySelector('video[data-slot=\"{slot}\"]').ended", timeout=20_000)
    for slot in slots:
        if page.locator(f"#value-{slot}").count():
            show_with_the_keyboard(page, slot)
            press(page, page.locator(f"#value-{slot}"), "ArrowRight")
    answer = page.locator("button[name=answer][value=left]")
    press(page, answer if answer.count() else page.get_by_role("button", name="Submit ratings"))
    strength = page.locator("button[name=strength]")
    if strength.count():  # the strength of a choice, asked once A or B is chosen: its button sends the answer
        strength.first.wait_for()
        press(page, strength.last)


def nothing_moves_but_clips(page) -> bool:
    """Reduced motion is asked for and honoured: no CSS animation or transition runs, no smooth scrolling."""
    return page.evaluate("""() => matchMedia("(prefers-reduced-motion: reduce)").matches
        && document.getAnimations().length === 0
        && getComputedStyle(document.documentElement).scrollBehavior !== "smooth\"""")


def keyboard_path(page, study: Study, findings: Findings, device: str) -> str:
    """Take the whole participant path with the keyboard alone, checking that nothing moves on
    each page and that each rating control has a name; returns the last page's text. axe-core
    looks at the first two rating pages (practice, then rated), which reduced motion changes
    (a clip waits for its play button); every page, as it is drawn otherwise, is the walk of
    `every_page`'s to check."""
    def look(name: str, with_axe: bool = False) -> None:
        assert nothing_moves_but_clips(page), name
        findings.check(page, f"{device} keyboard: {name}", with_axe)

    assert page.locator("#device-ok").count(), page.inner_text("body")
    page.wait_for_function("() => !document.getElementById('device-ok').disabled", timeout=20_000)
    look("device-check")
    press(page, page.get_by_role("button", name="Continue"))
    page.get_by_role("button", name="I agree to take part").wait_for()
    look("consent")
    press(page, page.get_by_role("button", name="I agree to take part"))
    page.get_by_role("radio", name="yes").wait_for()
    press(page, page.get_by_role("radio", name="yes"), "Space")
    assert page.get_by_role("radio", name="yes").is_checked()
    look("screening")
    press(page, page.get_by_role("button", name="Continue"))
    page.get_by_role("button", name="Start").wait_for()
    look("instructions")
    press(page, page.get_by_role("button", name="Start"))
    page.wait_for_selector("form[data-next-page]")
    pages = 0
    while page.locator("form[data-next-page]").count():
        pages += 1
        page.wait_for_selector("video:not([data-upcoming])")
        shown = page_id(page)
        look(f"rating page {pages}", with_axe=pages <= 2)
        answer_with_the_keyboard(page)
        page.wait_for_function(f"() => document.querySelector('main')?.dataset.pageId !== '{shown}'", timeout=20_000)
        page.wait_for_load_state()
    participant = Participant.objects.get(study=study, platform_id=f"keys-{device}")
    assert pages == 1 + participant.assignments.values("page").distinct().count()  # the practice page and each rated one
    page.get_by_role("textbox", name="Any comments?").wait_for()
    look("survey")
    press(page, page.get_by_role("textbox", name="Any comments?"), "A")
    press(page, page.get_by_role("button", name="Continue"))
    page.get_by_role("button", name="Copy the code").wait_for()
    look("end")
    tab_to(page, page.get_by_role("button", name="Copy the code"))
    return page.inner_text("body")


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("design", DESIGNS)
def test_every_participant_page_passes_axe_and_the_path_works_by_keyboard_with_reduced_motion(
        browser, live_server, clip_video, axe, settings, tmp_path, design):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_design_study(design, clip_video)
    link = f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=%s&STUDY_ID=S1&SESSION_ID=X1"
    findings = Findings(axe)
    for device, screen in SCREENS.items():
        context = browser.new_context(**screen, reduced_motion="reduce")
        page = context.new_page()
        page.goto(link % f"keys-{device}")
        done = keyboard_path(page, study, findings, device)
        assert "You have finished the study" in done and study.completion_code in done
        context.close()
        context = browser.new_context(**screen)  # the pages answering does not reach: reached by setting progress
        page = context.new_page()
        page.goto(link % f"every-{device}")
        every_page(study, page, f"{design}-{device}", pid=f"every-{device}",
                   on_page=lambda name, device=device, page=page: findings.check(page, f"{device}: {name}"))
        context.close()
    findings.assert_none()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_the_message_pages_pass_axe(browser, live_server, clip_video, axe, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=1, training_clips=0,
                       bad_checks=0, natural_checks=0)
    closed = make_study(owner_name="other", is_open=False)
    findings = Findings(axe)
    context = browser.new_context(**SCREENS[device])
    page = context.new_page()
    for name, url, status in (("closed study", f"/p/{closed.key}/?PROLIFIC_PID=late", 404),
                              ("no study", "/p/nothing-here/?PROLIFIC_PID=lost", 404),
                              ("no platform id", f"/p/{study.key}/", 400)):
        assert page.goto(live_server.url + url).status == status, name
        findings.check(page, name)
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=P1&STUDY_ID=S1&SESSION_ID=first")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("#clip")
    Stimulus.objects.update(duration_s=60.0)  # every answer now comes too soon: the refusal's page
    page.evaluate("() => document.querySelectorAll('button[name=value]').forEach((b) => { b.disabled = false; })")
    page.click("button[name=value][value='4']")
    page.wait_for_selector("text=Please watch the clip to its end")
    findings.check(page, "answer too soon")
    other = browser.new_context(**SCREENS[device]).new_page()
    assert other.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=P1&STUDY_ID=S1&SESSION_ID=second").status == 409
    findings.check(other, "started elsewhere")
    other.context.close()
    context.close()
    findings.assert_none()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", SCREENS)
def test_the_researchers_pages_pass_axe(browser, live_server, axe, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = rated_study()
    context = browser.new_context(**SCREENS[device])
    page = log_in(context, live_server, study)
    page.wait_for_url(f"**{reverse('study-list')}")  # axe is to check the study list, not the login page
    findings = Findings(axe)
    findings.check(page, "study list after login")
    report = page.request.post(f"{live_server.url}{reverse('study-report', args=[study.pk])}", headers={
        "X-CSRFToken": next(c["value"] for c in context.cookies() if c["name"] == "csrftoken"),
        "Referer": live_server.url}, max_redirects=0)
    assert report.status == 302, report.text()
    urls = {**researcher_urls(study), "study-plan": reverse("study-plan", args=[study.pk]),
            "report": report.headers["location"]}
    for name, url in urls.items():
        assert page.goto(live_server.url + url).status == 200, name
        findings.check(page, name)
    context.close()
    login = browser.new_context(**SCREENS[device]).new_page()
    login.goto(f"{live_server.url}{reverse('login')}")
    findings.check(login, "login")
    login.context.close()
    findings.assert_none()
