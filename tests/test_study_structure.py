"""The study app's structure: domain modules know nothing of the task queue, and the
participant's path is one table that a new page type joins with one entry and one template."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest
from django.shortcuts import redirect
from django.test import Client
from django.urls import clear_url_caches, reverse

from studyapp.models import Participant
from studyapp.participants import path as participant_path
from studyapp.participants.path import Step, stage
import studyapp.urls
from tests.study_fixtures import make_study

STUDYAPP = Path(__file__).resolve().parents[1] / "studyapp"
QUEUE_MODULES = ("celery", "kombu", "studyapp.server.celery", "studyapp.tasks", "studyapp.stimuli.dispatch", "studyapp.server.health")


def _source(module: str) -> Path:
    return STUDYAPP / f"{module.removeprefix('studyapp.').replace('.', '/')}.py"


def _imports(module: str) -> set[str]:
    """Every module ``module`` imports, at any level of its code (function bodies included)."""
    tree = ast.parse(_source(module).read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def _studyapp_closure(module: str) -> dict[str, set[str]]:
    """``module`` and the studyapp modules it reaches through imports, each with its imports."""
    seen: dict[str, set[str]] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen[name] = _imports(name)
        todo += [i for i in seen[name] if i.startswith("studyapp.") and _source(i).is_file()]
    return seen


def test_stimulus_logic_reaches_no_task_queue_module():
    closure = _studyapp_closure("studyapp.stimuli.clips")
    assert "studyapp.models" in closure  # the walk follows studyapp's own imports
    reached = {name: sorted(i for i in imports if i.split(".")[0] in ("celery", "kombu") or i in QUEUE_MODULES)
               for name, imports in closure.items()}
    assert {name: found for name, found in reached.items() if found} == {}


QUESTIONNAIRE = """{% extends "studyapp/participant/base.html" %}{% block content %}<h1>About you</h1>
<form method="post" action="{% url 'participant-questionnaire' key=study.key %}">{% csrf_token %}
<input type="hidden" name="age" value="{{ suggested_age }}"></form>{% endblock %}"""


@pytest.fixture
def path_with_questionnaire(tmp_path, settings, monkeypatch):
    """The participant path with a questionnaire after consent: one Step and one template, nothing else."""
    (tmp_path / "studyapp" / "participant").mkdir(parents=True)
    (tmp_path / "studyapp" / "participant" / "questionnaire.html").write_text(QUESTIONNAIRE)
    settings.TEMPLATES = [{**settings.TEMPLATES[0], "DIRS": [tmp_path]}]

    def answer(request, study, participant):
        participant.platform_data = {**participant.platform_data, "age": request.POST["age"]}
        participant.save(update_fields=["platform_data"])
        return redirect("participant-page", key=study.key)

    questionnaire = Step("questionnaire", "questionnaire.html", pending=lambda p: "age" not in p.platform_data,
                         page=lambda study, participant: {"suggested_age": 42}, submit=answer)
    after_consent = 1 + [step.name for step in participant_path.PATH].index("consent")
    monkeypatch.setattr(participant_path, "PATH", (*participant_path.PATH[:after_consent], questionnaire,
                                                   *participant_path.PATH[after_consent:]))
    importlib.reload(studyapp.urls)  # the URLs are made from the path
    clear_url_caches()
    yield
    monkeypatch.undo()
    importlib.reload(studyapp.urls)
    clear_url_caches()


@pytest.mark.django_db
def test_a_new_page_type_is_one_step_in_the_path_and_one_template(path_with_questionnaire):
    study = make_study(clips_per_participant=3, training_clips=0)
    client = Client()
    client.get(reverse("participant-enter", args=[study.key]), {"PROLIFIC_PID": "q-1"})
    client.post(reverse("participant-consent", args=[study.key]), {"agree": "yes"})
    participant = Participant.objects.get(study=study)
    assert stage(participant) == "questionnaire"
    page = client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert "About you" in page and 'value="42"' in page
    # Its form is guarded like every step's: not before its turn, and not once passed.
    assert client.post(reverse("participant-instructions", args=[study.key])).status_code == 409
    assert client.post(reverse("participant-questionnaire", args=[study.key]), {"age": "42"}).status_code == 302
    participant.refresh_from_db()
    assert participant.platform_data["age"] == "42" and stage(participant) == "instructions"
    assert client.post(reverse("participant-questionnaire", args=[study.key]), {"age": "7"}).status_code == 409


@pytest.mark.django_db
def test_a_step_added_to_the_path_is_in_the_preview_without_touching_the_preview(path_with_questionnaire):
    from studyapp.researchers.setup.preview import preview_pages

    study = make_study(clips_per_participant=3, training_clips=0)
    pages = preview_pages(study)
    assert [page.name for page in pages] == ["consent", "questionnaire", "instructions", "a page to rate", "completion"]
    assert pages[1].template == "questionnaire.html" and pages[1].context == {"suggested_age": 42}

