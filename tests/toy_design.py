"""A toy rating design, added the way docs/architecture.md says a design is added: this
module, its template (``TEMPLATE``) and one entry in ``studyapp.designs.registry.DESIGNS``.

Thumbs: one clip a page, thumbs up (1) or down (0). No targets, no practice, no checks.
"""

from __future__ import annotations

import random
from collections import Counter
from datetime import datetime

from django.http import QueryDict

from studyapp.designs.answers import client_times
from studyapp.designs.design import Answer, Design, PlannedPage
from studyapp.models import Stimulus, Study, System
from studyapp.participants.refusal import AnswerRefused

TEMPLATE = """{% extends "studyapp/participant/base.html" %}{% block content %}
<p class="meta">{{ heading }}</p>
{% for clip in clips %}<video src="{{ clip.video_url }}" data-seconds="{{ clip.seconds }}"></video>{% endfor %}
<form method="post" action="{% url action key=study.key %}">{% csrf_token %}
{% for name, value in form.items %}<input type="hidden" name="{{ name }}" value="{{ value }}">{% endfor %}
<button type="submit" name="thumb" value="up">Thumbs up</button>
<button type="submit" name="thumb" value="down">Thumbs down</button></form>{% endblock %}"""


class Thumbs(Design):
    template = "thumbs.html"
    page_word = "Clip"

    def loads(self, study: Study, cutoff: datetime) -> Counter:
        return Counter()

    def plan(self, study: Study, rendered: list[Stimulus], loads: Counter, count: int,
             rng: random.Random) -> list[PlannedPage]:
        return [PlannedPage([s]) for s in rendered if s.system.role == System.Role.MODEL][:count]

    def practice(self, study, rendered, planned, rng) -> list[int]:
        return []

    def read_answer(self, study: Study, form: QueryDict) -> Answer:
        thumbs = {"up": 1, "down": 0}
        if form.get("thumb") not in thumbs:
            raise AnswerRefused("thumbs up or down, please")
        return Answer(form.get(self.form_field, ""), {1: client_times(form)}, values={1: thumbs[form["thumb"]]})

    def check_answer(self, study: Study, answer: Answer, slots: list[int]) -> None:
        pass

    def exclusion_reason(self, rules, study, page, answer) -> str:
        return ""
