"""A German study end to end in a real browser (headless Debian Chromium): from the device
check and consent to the completion code, on a phone, every page (and what its scripts write
into it) in German but the researcher's own texts, none wider than the screen ($SHOTS_DIR:
each saved as a PNG); and a side-by-side page of a German study, whose
script's notes are German too."""

from __future__ import annotations

import pytest

from studyapp.models import Participant, Question, Rating, Study
from tests.study_fixtures import current_clip, make_study
from tests.test_participant_language import ENGLISH, without_researcher_texts
from tests.test_participant_pages_browser import PHONE, play_to_end, shoot, skip_to_ratings, slots_on_page
from tests.test_study_browser import browser, clip_video, wait_for_clip_end  # noqa: F401 (fixtures)

pytestmark = pytest.mark.slow

CLIP_SECONDS = 1.0
SHOWN = """() => [document.title, document.body.innerText,
                   ...[...document.querySelectorAll("[aria-label]")].map((e) => e.getAttribute("aria-label"))].join(" ")"""


def english_on(page, study: Study) -> list[str]:
    """The English words the page shows or reads out, the researcher's texts left out."""
    return ENGLISH.findall(without_researcher_texts(page.evaluate(SHOWN), study))


@pytest.mark.django_db(transaction=True)
def test_a_german_study_runs_end_to_end_in_german(browser, live_server, clip_video, settings, tmp_path):  # noqa: F811
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=4, training_clips=1,
                       instructed_checks=1, language=Study.Language.GERMAN, device_check=True,
                       min_screen_width=320, min_screen_height=400, title="Natürlichkeit von Bewegung")
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="age", text="How old are you?",
                            kind=Question.Kind.NUMBER, minimum=18, maximum=99)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="remarks", text="Any remarks?",
                            kind=Question.Kind.TEXT, required=False)
    context = browser.new_context(**PHONE)
    page = context.new_page()
    seen: list[tuple[str, list[str]]] = []

    def look(name: str) -> None:
        assert page.evaluate("document.documentElement.lang") == "de", name
        # The German words, longer than the English, still fit a phone's width.
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth"), name
        shoot(page, f"german-{name.replace(' ', '-')}")
        seen.append((name, english_on(page, study)))

    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=de-1&STUDY_ID=S1&SESSION_ID=X1")
    page.wait_for_selector("#check-video strong:text('ja')", timeout=20_000)  # written by the page's script
    look("device check")
    page.get_by_role("button", name="Weiter").click()
    page.wait_for_selector("text=Einwilligung")
    look("consent")
    page.get_by_role("button", name="Ich stimme der Teilnahme zu").click()
    page.wait_for_selector("text=Zunächst einige Fragen")
    page.fill("input[type=number]", "150")  # out of range: the browser's own check; then the server's refusal
    page.evaluate("document.querySelector('form.questions').noValidate = true")
    page.get_by_role("button", name="Weiter").click()
    page.wait_for_selector("text=Das hat nicht geklappt")
    assert "„How old are you?“: Bitte geben Sie eine ganze Zahl von 18 bis 99 an" in page.inner_text("body")
    look("refused answer")
    page.get_by_role("link", name="Zurück zur Studie").click()
    page.fill("input[type=number]", "30")
    page.get_by_role("button", name="Weiter").click()
    page.wait_for_selector("text=Anleitung")
    look("instructions")
    page.get_by_role("button", name="Beginnen").click()
    page.wait_for_selector("text=Übungsclip 1 von 1 (wird nicht gespeichert)")
    look("practice")
    wait_for_clip_end(page)
    page.get_by_role("button", name="3", exact=True).click()
    participant = Participant.objects.get(study=study, platform_id="de-1")
    while (assignment := current_clip(participant)) is not None:
        page.wait_for_selector(f"input[name=assignment][value='{assignment.token}']", state="attached")
        assert f"Clip {assignment.page + 1} von 4" in page.inner_text("body")
        if assignment.expected:
            assert f"Aufmerksamkeitsprüfung: Antworten Sie bitte mit {assignment.expected}" in page.inner_text("body")
        look(f"clip {assignment.position}")
        wait_for_clip_end(page)
        page.get_by_role("button", name=assignment.expected or "4", exact=True).click()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{assignment.token}')")
    page.wait_for_selector("text=Zum Abschluss einige Fragen")
    look("closing questions")
    page.get_by_role("button", name="Weiter").click()
    page.wait_for_selector("text=Vielen Dank!")
    page.get_by_role("button", name="Code kopieren").click()
    page.wait_for_function("() => document.getElementById('copy-status').textContent !== ''")
    assert page.inner_text("#copy-status") in ("Kopiert.", "Markiert: Kopieren Sie ihn mit dem Kopierbefehl Ihres Geräts.")
    look("completion")
    context.close()
    assert [name for name, _ in seen][:5] == ["device check", "consent", "refused answer", "instructions", "practice"]
    assert len(seen) == 5 + 4 + 2  # the four clips, the closing questions and the completion
    assert [(name, words) for name, words in seen if words] == []
    participant.refresh_from_db()
    assert participant.finished_at is not None and participant.answers == {"age": 30}
    assert Rating.objects.filter(assignment__participant=participant).count() == 4


@pytest.mark.django_db(transaction=True)
def test_a_german_side_by_side_pages_script_notes_are_german(browser, live_server, clip_video, settings,  # noqa: F811
                                                             tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=2, bad_checks=0, design="side-by-side",
                       scale_min=0, scale_max=100, pages_per_participant=2, language=Study.Language.GERMAN)
    page = browser.new_context(**PHONE).new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=de-2&STUDY_ID=S1&SESSION_ID=X1")
    skip_to_ratings(page, study, "de-2")
    for slot in slots_on_page(page):
        play_to_end(page, slot)
    assert "(noch nicht bewegt: Clip A, B, C)" in page.inner_text("#move-note")
    assert page.get_by_role("button", name="Bewertungen absenden").is_disabled()
    assert page.get_by_role("tab", name="A").count() == 1 and page.get_by_label("Bewertung von Clip A:").count() == 1
    assert english_on(page, study) == []
    page.context.close()
