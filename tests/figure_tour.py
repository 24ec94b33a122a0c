"""Screenshots of a study of three rigs on its one display figure (NAT on the Bandai-Namco
rig, the same walk submitted on CMU's and on ACCAD's), as a participant sees each clip on
a desktop and a phone, and the CMU system's figure page and the monitor's warnings.

Not part of the test run (its name does not start with test_): run it with
``python -m pytest -p no:xdist tests/figure_tour.py``; it writes to $FIGURE_TOUR_DIR
(default docs/tour/figure/).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from django.conf import settings as django_settings
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse

from tests.test_crowd_browser import PHONE
from studyapp.models import Participant, Study
from tests.test_study_browser import browser, wait_for_clip_end  # noqa: F401 (fixture)
from tests.test_study_display_figure import make_mixed_study, rendered
from tests.test_study_researcher import queue  # noqa: F401 (fixture)

OUT = Path(os.environ.get("FIGURE_TOUR_DIR", Path(__file__).resolve().parents[1] / "docs" / "tour" / "figure"))
DESKTOP = {"viewport": {"width": 1200, "height": 800}}


@pytest.mark.django_db(transaction=True)
def test_figure_tour(browser, live_server, settings, tmp_path, queue, motion_data_2):
    OUT.mkdir(parents=True, exist_ok=True)
    study = make_mixed_study(settings, tmp_path, motion_data_2, (640, 480), clips_per_participant=3,
                             training_clips=0, bad_checks=0, natural_checks=0, instructed_checks=0)
    stimuli = rendered(study)
    client = Client()
    client.force_login(User.objects.get(username="researcher"))
    session = client.cookies[django_settings.SESSION_COOKIE_NAME].value
    cookie = {"name": django_settings.SESSION_COOKIE_NAME, "value": session, "url": live_server.url}
    for device, options in (("desktop", DESKTOP), ("phone", PHONE)):
        context = browser.new_context(**options)
        context.add_cookies([cookie])
        page = context.new_page()
        cmu = study.systems.get(name="CMU")
        page.goto(live_server.url + reverse("study-system-figure", args=[study.pk, cmu.pk]))
        page.screenshot(path=OUT / f"figure-page-{device}.png", full_page=True)
        page.goto(live_server.url + reverse("study-monitor", args=[study.pk]))
        page.screenshot(path=OUT / f"monitor-{device}.png", full_page=True)
        context.close()

    Study.objects.filter(pk=study.pk).update(is_open=True, completion_code="FIGURE1", require_full_play=False)
    link = f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=%s&STUDY_ID=S1&SESSION_ID=%s"
    for device, options in (("desktop", DESKTOP), ("phone", PHONE)):
        context = browser.new_context(**options)
        page = context.new_page()
        page.goto(link % (f"{device}-1", device))
        page.get_by_role("button", name="I agree to take part").click()
        page.get_by_role("button", name="Start").click()
        for clip in range(1, 1 + len(stimuli)):  # every system's clip of the one control, in the participant's order
            page.wait_for_selector("#clip")
            page.wait_for_function("() => document.getElementById('clip').readyState >= 2", timeout=20_000)
            page.evaluate("() => { const v = document.getElementById('clip'); v.pause(); v.currentTime = 1.5; }")
            page.wait_for_timeout(500)
            page.screenshot(path=OUT / f"clip-{clip}-{device}.png")
            page.evaluate("() => { const v = document.getElementById('clip'); v.currentTime = 0; v.play(); }")
            wait_for_clip_end(page)
            token = page.input_value("input[name=assignment]")
            page.locator("button[name=value][value='4']").click()
            page.wait_for_load_state()
            page.wait_for_function(f"() => !document.body.innerHTML.includes('{token}')")
        context.close()
    # Which system each participant's clip was, for the reader of the screenshots (participants never learn it).
    order = [f"clip-{k}-{device}: {a.stimulus.system.name}"
             for device, p in zip(("desktop", "phone"), Participant.objects.filter(study=study).order_by("pk"))
             for k, a in enumerate(p.assignments.order_by("position").select_related("stimulus__system"), start=1)]
    (OUT / "clips.txt").write_text("\n".join(order) + "\n")
