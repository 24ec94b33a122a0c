"""Participant pages in the study's language: every word of the app's own on them is marked
for translation, the German catalogue translates every one and its compiled file is the
one committed, and a German study's pages (every step of every design, its messages and
refusals) hold no English but the researcher's own texts.
"""

from __future__ import annotations

import ast
import gettext
import json
import random
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest
from django.template.base import Lexer, TokenType
from django.test import Client
from django.urls import reverse
from django.utils import translation

from studyapp.bundles.writing import study_record
from studyapp.definitions.describe import describe_study
from studyapp.designs.registry import design_of
from studyapp.models import Participant, Question, Stimulus, Study
from studyapp.participants.path import screen_need
from studyapp.preregistration.contents import plan_contents
from studyapp.researchers.setup.forms import StudyForm
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.test_hostile_numbers import study_fields
from tests.study_fixtures import make_study
from tests.test_study_designs import PAIRWISE, SIDE_BY_SIDE

ROOT = Path(__file__).resolve().parents[1] / "studyapp"
TEMPLATES = ROOT / "templates"
# Every template a participant can be shown: their pages, and the error pages.
PARTICIPANT_TEMPLATES = sorted([*(TEMPLATES / "studyapp" / "participant").glob("*.html"),
                                *(TEMPLATES / name for name in ("400.html", "403.html", "404.html", "413.html",
                                                                "500.html", "error_base.html"))])
SCRIPTS = [ROOT / "static" / "studyapp" / name for name in ("clip-page.js", "page-clips.js", "next-page.js")]
CATALOGUE = ROOT / "locale" / "de" / "LC_MESSAGES"
# Attributes that a browser shows or reads out.
SHOWN_ATTRIBUTES = {"aria-label", "title", "alt", "placeholder"}
# Blocks whose text is no text but part of a tag (a class name).
TAG_BLOCKS = {"body_class"}
WORD = re.compile(r"[A-Za-z]{2,}")
# A sentence in a script: a capital, a word, a space and more (not a selector or an event name).
SENTENCE = re.compile(r"""(["'`])[A-Z][a-z]+ [^"'`]*[a-z][^"'`]*\1""")
# Words that a German page never holds, and that nearly every English sentence has.
ENGLISH = re.compile(r"\b(the|you|your|please|and|is|are|of|to|this|that|not|has|been|will|which|each|every|"
                     r"play|page|rating|answer|agree|continue|start|thank|back|better|closer|preference)\b", re.I)

pytestmark = pytest.mark.django_db


class _Skeleton(HTMLParser):
    """Text and shown attribute values of a template's HTML, outside scripts and styles, with their lines."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.texts: list[tuple[int, str]] = []
        self.scripts: list[tuple[int, str]] = []
        self._raw: str | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self._raw = tag if tag in ("script", "style") else None
        self.texts += [(self.getpos()[0], value) for name, value in attrs if name in SHOWN_ATTRIBUTES and value]

    def handle_endtag(self, tag: str) -> None:
        self._raw = None

    def handle_data(self, data: str) -> None:
        (self.scripts if self._raw == "script" else [] if self._raw else self.texts).append((self.getpos()[0], data))


def untranslated(path: Path, root: Path = ROOT) -> list[str]:
    """"file:line: text" for each text of a template's own that no {% translate %} or
    {% blocktranslate %} holds (values and tags stand as §; a script's sentences count too)."""
    skeleton, inside, comment = [], 0, False
    for token in Lexer(path.read_text()).tokenize():
        contents = token.contents.split()
        name = contents[0] if token.token_type == TokenType.BLOCK and contents else ""
        if name == "comment" or name == "block" and contents[1:2] and contents[1] in TAG_BLOCKS:
            comment = True
        elif name in ("endcomment", "endblock"):
            comment = False
        elif name in ("blocktranslate", "blocktrans"):
            inside += 1
        elif name in ("endblocktranslate", "endblocktrans"):
            inside -= 1
        if token.token_type == TokenType.TEXT and not inside and not comment:
            skeleton.append(token.contents)
        else:  # a value, a tag or translated text: its place, keeping the lines
            kept = token.contents if token.token_type == TokenType.TEXT else ""
            skeleton.append("§" + "\n" * kept.count("\n"))
    parser = _Skeleton()
    parser.feed("".join(skeleton))
    parser.close()
    where = path.relative_to(root)
    found = [f"{where}:{line}: {text.strip()!r}" for line, text in parser.texts if WORD.search(text.replace("§", " "))]
    found += [f"{where}:{line}: {match.group(0)!r}" for line, text in parser.scripts
              for match in SENTENCE.finditer(text)]
    return found


def test_the_scanner_finds_text_outside_translation_tags(tmp_path):
    page = tmp_path / "page.html"
    page.write_text('{% load i18n %}<p>{% translate "Fine" %}</p>\n<button aria-label="Close {{ x }}">§</button>\n'
                    '{% blocktranslate %}Also fine {{ x }}{% endblocktranslate %}\n<p>Clip {{ label }}</p>\n'
                    '<script>note.textContent = "Please wait for it.";</script>{# A comment #}')
    found = [entry.split(": ", 1) for entry in untranslated(page, tmp_path)]
    assert [(where.rsplit(":", 1)[1], text) for where, text in found] == [
        ("2", "'Close §'"), ("4", "'Clip §'"), ("5", "'\"Please wait for it.\"'")]


@pytest.mark.parametrize("path", PARTICIPANT_TEMPLATES, ids=lambda path: path.name)
def test_every_text_of_a_participant_template_is_marked_for_translation(path):
    assert untranslated(path) == []


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda path: path.name)
def test_the_participant_scripts_hold_no_sentence_of_their_own(path):
    text = path.read_text()
    sentences = [match.group(0) for line in text.splitlines() if not line.lstrip().startswith("//")
                 for match in SENTENCE.finditer(line)]
    assert sentences == []


def catalogue_entries(po: Path) -> list[dict]:
    """The entries of a .po file: msgid, msgstr and flags (the header left out)."""
    entries, entry, field = [], None, None
    for line in po.read_text(encoding="utf-8").splitlines() + [""]:
        if not line.strip():
            if entry and entry["msgid"]:
                entries.append(entry)
            entry, field = None, None
            continue
        entry = entry or {"msgid": "", "msgstr": "", "flags": set()}
        if line.startswith("#,"):
            entry["flags"] |= {flag.strip() for flag in line[2:].split(",")}
        elif line.startswith("#"):
            continue
        elif line.startswith(("msgid ", "msgstr ")):
            field, value = line.split(" ", 1)
            entry[field] = ast.literal_eval(value)
        elif line.startswith('"') and field:
            entry[field] += ast.literal_eval(line)
    return entries


def test_every_german_message_is_translated_with_its_placeholders():
    entries = catalogue_entries(CATALOGUE / "django.po")
    assert len(entries) > 100
    for entry in entries:
        assert entry["msgstr"].strip(), f"no German for {entry['msgid']!r}"
        assert "fuzzy" not in entry["flags"], f"fuzzy German for {entry['msgid']!r}"
        assert sorted(re.findall(r"%\(\w+\)s", entry["msgid"])) == sorted(re.findall(r"%\(\w+\)s", entry["msgstr"])), \
            entry["msgid"]
        assert " du " not in f" {entry['msgstr'].lower()} ", entry["msgstr"]  # formal throughout: Sie


def test_the_committed_compiled_catalogue_is_the_translations_of_the_po_file():
    with (CATALOGUE / "django.mo").open("rb") as compiled:
        catalog = gettext.GNUTranslations(compiled)._catalog
    assert {k: v for k, v in catalog.items() if k} == {
        entry["msgid"]: entry["msgstr"] for entry in catalogue_entries(CATALOGUE / "django.po")}, \
        "django.mo is out of date: run make messages"


# Each design's study (its pages with practice, and a screening and a closing question).
DESIGNS = {
    "single": (make_study, {}),
    "single, scale of 10": (make_study, {"scale_min": 1, "scale_max": 10}),
    "side-by-side": (make_study, SIDE_BY_SIDE),
    "pairwise": (make_study, PAIRWISE),
    "pairwise with strengths": (make_study, {**PAIRWISE, "preference_strengths": 3}),
    "pairwise ABX": (make_study, {**PAIRWISE, "abx": True}),
    "appropriateness": (make_appropriateness_study, {}),
}
# The researcher's own texts (title, instructions, consent, question, labels, questions): shown as written.
RESEARCHER_FIELDS = ("title", "instructions", "consent_text", "question", "label_min", "label_max")


def visible_text(html: str) -> str:
    """What a page shows and reads out: its text and shown attributes, outside scripts,
    plus the words its scripts may show (``studyappText``); a preview's banner, the
    researcher's, left out."""
    parser = _Skeleton()
    parser.feed(re.sub(r'<p class="preview-banner".*?</p>', "", html, flags=re.S))
    shown = " ".join(text for _, text in parser.texts)
    words = re.search(r'<script id="studyapp-text" type="application/json">(.*?)</script>', html, re.S)
    return " ".join([shown, *(json.loads(words.group(1)).values() if words else [])])


def without_researcher_texts(text: str, study: Study) -> str:
    for value in [*(getattr(study, name) for name in RESEARCHER_FIELDS),
                  *(part for question in study.questions.all() for part in (question.text, *question.choice_list))]:
        for line in value.splitlines():
            text = text.replace(line.strip(), " ")
    return text


def german_study(make, settings: dict) -> Study:
    study = make(**settings, training_clips=2, language=Study.Language.GERMAN, device_check=True,
                 min_screen_width=320, min_screen_height=200, instructed_checks=1, is_open=False)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="age", text="How old are you?",
                            kind=Question.Kind.NUMBER, minimum=18, maximum=99)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="remarks", text="Any remarks?",
                            kind=Question.Kind.TEXT, required=False)
    return study


def preview_pages(study: Study) -> dict[str, str]:
    """The researcher's preview of every step, step name -> HTML."""
    client = Client()
    client.force_login(study.owner)
    pages, index = {}, 0
    while True:
        response = client.get(reverse("study-preview-page", args=[study.pk, index]))
        if response.status_code != 200:
            return pages
        html = response.content.decode()
        pages[f"page {index + 1}"] = html
        if reverse("study-preview-page", args=[study.pk, index + 1]) not in html:
            return pages
        index += 1


@pytest.mark.parametrize("design", list(DESIGNS))
def test_every_page_of_a_german_study_holds_no_english_but_the_researchers_texts(design):
    make, settings = DESIGNS[design]
    study = german_study(make, settings)
    pages = preview_pages(study)
    assert len(pages) >= 7  # device, consent, screening, instructions, practice, rating, completion
    for name, html in pages.items():
        assert '<html lang="de">' in html, name
        english = ENGLISH.findall(without_researcher_texts(visible_text(html), study))
        assert english == [], (name, english)
    every = "".join(pages.values())
    for german in ("Prüfung Ihres Geräts", "Einwilligung", "Zunächst einige Fragen", "Anleitung",
                   r"Übungs(seite|clip) 1 von \d+ \(wird nicht gespeichert\)", r"(Seite|Clip) 1 von \d+",
                   "Zum Abschluss einige Fragen", "Vielen Dank!"):
        assert re.search(german, every), german


@pytest.mark.parametrize("design", list(DESIGNS))
def test_every_designs_instructed_check_is_worded_in_german(design):
    make, settings = DESIGNS[design]
    study = make(**settings, language=Study.Language.GERMAN)
    clips = list(Stimulus.objects.filter(study=study).select_related("system")[:2])
    rules = design_of(study)
    expected = rules.instructed_answer(study, clips, random.Random(0))
    with translation.override(study.language):
        instruction = rules.instruction(study, expected)
    assert instruction.startswith("Aufmerksamkeitsprüfung: ") and ENGLISH.findall(instruction) == [], instruction
    assert rules.instruction(study, expected).startswith("Attention check: ")


def test_the_device_checks_screen_size_is_worded_in_the_language_in_force():
    study = make_study(language=Study.Language.GERMAN, min_screen_width=800)
    with translation.override(study.language):
        assert screen_need(study) == "mit mindestens 800 Pixeln Breite"
    assert screen_need(study) == "at least 800 pixels wide"  # the thread's language came back


def enter(client: Client, study: Study, pid: str = "p1") -> Participant:
    response = client.get(f"/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    assert response.status_code == 302
    return Participant.objects.get(study=study, platform_id=pid)


def test_messages_and_refusals_come_in_the_studys_language_and_english_without_a_study():
    study = make_study(language=Study.Language.GERMAN)
    client = Client()
    enter(client, study)
    refused = client.post(f"/p/{study.key}/instructions/")  # before consent: not the current step
    assert refused.status_code == 409 and "Dieser Schritt ist nicht der aktuelle" in refused.content.decode()
    assert "Das hat nicht geklappt" in refused.content.decode() and "Zurück zur Studie" in refused.content.decode()
    missing = client.get(f"/p/{study.key}/nowhere/")
    assert missing.status_code == 404 and "Seite nicht gefunden" in missing.content.decode()
    declined = client.post(f"/p/{study.key}/consent/", {"agree": "no"}).content.decode()
    assert "Sie haben sich entschieden, nicht teilzunehmen" in declined and '<html lang="de">' in declined
    no_study = Client().get("/p/no-such-study/").content.decode()
    assert "There is no study at this address" in no_study and '<html lang="en-us">' in no_study
    english = make_study(owner_name="other", title="An English study")
    assert "I agree to take part" in Client().get(
        f"/p/{english.key}/?PROLIFIC_PID=e1&STUDY_ID=S1&SESSION_ID=X1", follow=True).content.decode()


def test_an_expired_form_is_explained_in_the_studys_language():
    study = make_study(language=Study.Language.GERMAN)
    client = Client(enforce_csrf_checks=True)
    enter(client, study)
    response = client.post(f"/p/{study.key}/consent/", {"agree": "yes"})
    assert response.status_code == 403 and "Diese Seite war abgelaufen" in response.content.decode()


def test_refusals_made_before_the_view_come_in_the_studys_language_on_its_pages_only():
    study = make_study(language=Study.Language.GERMAN)
    client = Client()
    enter(client, study)
    nul = client.get(f"/p/{study.key}/now/", {"x": "a\x00"})
    page = nul.content.decode()
    assert nul.status_code == 400 and '<html lang="de">' in page, page[:300]
    assert "Der Parameter x der Adresse enthält ein NUL-Zeichen" in page and "Ungültige Anfrage" in page
    too_large = client.post(f"/p/{study.key}/rate/", data=b"", content_type="application/x-www-form-urlencoded",
                            CONTENT_LENGTH=str(10**9))
    page = too_large.content.decode()
    assert too_large.status_code == 413 and "Der Upload hat 1.000,0 MB; diese Seite nimmt höchstens" in page, page[-600:]
    english = Client().post("/studies/new/", {"title": "a\x00"})  # a researcher's page: English, as they all are
    assert english.status_code == 400 and "The form field title holds a NUL character" in english.content.decode()
    no_study = Client().get("/p/no-such-study/now/", {"x": "a\x00"}).content.decode()
    assert "The query parameter x holds a NUL character" in no_study


def test_the_study_form_sets_the_language_and_one_from_before_the_setting_keeps_it():
    study = make_study(controls=0, is_open=False)
    form = StudyForm(study_fields(language="de"), instance=study)
    assert form.is_valid(), form.errors
    assert form.save().language == "de"
    form = StudyForm(study_fields(), instance=Study.objects.get(pk=study.pk))  # no language field posted
    assert form.is_valid(), form.errors
    assert form.save().language == "de"
    assert "language" in StudyForm(study_fields(language="xx"), instance=study).errors


def test_the_language_is_a_setting_of_the_study_page_its_definition_bundle_and_plan():
    study = make_study(language=Study.Language.GERMAN, controls=0)
    assert StudyForm.SECTIONS[0][1][:2] == ("title", "language")
    assert dict(StudyForm().fields["language"].choices)["de"] == "German (Deutsch)"
    assert describe_study(study)["the_study"]["language"] == "de"
    assert study_record(study)["study"]["language"] == "de"
    assert plan_contents(study)["design"]["settings"]["language"] == "de"
    client = Client()
    client.force_login(study.owner)
    assert "<li>Language: de</li>" in client.get(reverse("study-plan", args=[study.pk])).content.decode()
