"""Random, oversized, non-finite and wrongly-typed values sent to every participant step
(every design's rating step and the entry link's query included) and every researcher
form (the study's and its items' edits, moves, removals, copies and retries, the report,
the crowd platform's page and the admin's study and control forms included), and the
uploads of a study definition and of a study bundle, which also get definitions and
bundles that name another researcher's checkpoint or motion, server folders, takes
outside their folder and planted sampled motion: whatever comes in, no answer is a server
error, and a refused request (4xx) changes no row. The crowd platform's answers are drawn
too (statuses, content types, headers and bodies, or bytes that are not HTTP, from its
API's stand-in on 127.0.0.1): the pages that send to it and read from it never answer 500,
and only an answer that confirms a request makes it done.

Each drawn form starts from a valid one, so that a hostile value gets past the fields
before it: some fields get hostile values (NaN, infinities, 5000 digits, 70,000
characters, JSON, control characters, drawn text and numbers), some are left out, some
are sent several times (a list where one value is expected), and made-up fields are
added. Every example runs in a transaction that is rolled back, so each starts from the
same rows. Examples are drawn reproducibly (``derandomize``) and few enough that each
test takes seconds.
"""

from __future__ import annotations

import io
import json
import re
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from django.conf import settings as django_settings
from django.contrib.auth.models import Permission, User
from django.core.files.uploadedfile import SimpleUploadedFile
from django.db import connection, transaction
from django.test import Client
from django.http import HttpResponse
from django.urls import reverse
from django.utils import timezone
from hypothesis import HealthCheck, given
from hypothesis import settings as fuzz_settings
from hypothesis import strategies as st

from generation.control import preset_path
from generation.motion.dataset_options import DatasetOptions
from studyapp.definitions import create_study_from_definition
from studyapp.bundles.manifest import entry_of
from studyapp.bundles.pseudonyms import export_key
from studyapp.bundles.writing import write_study_bundle
from studyapp.models import (Assignment, ControlSignal, Participant, PlatformAction, Question, Rating, Stimulus, Study,
                             System)
from studyapp.participants.views import _remember
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.platform_standins import ProlificStandIn, Raw, http_answer
from tests.test_study_definition_refusals import VALID, mutated_definition
from tests.study_fixtures import make_study
from tests.test_hostile_numbers import study_fields

pytestmark = [pytest.mark.django_db, pytest.mark.slow]

EXAMPLES = 40
FUZZ = fuzz_settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                     suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                            HealthCheck.data_too_large])

HOSTILE = ["nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e400", "1e-320", "9" * 400,
           "9" * 5000, "-" + "9" * 400, "-1", "0", "1", "2147483648", "99999999999", "1.5", "0x10", "1_000", "",
           " ", "true", "None", "null", "[]", "{}", '{"a": NaN}', "\x00", "\x0b", "\u2028", "é", "٣", "²",
           "<script>alert(1)</script>", "'; DROP TABLE studyapp_study; --", "../../etc/passwd", "a" * 70_000]
# Half the values are the tokens above, half drawn text and numbers (integers of any size).
VALUE = st.one_of(st.sampled_from(HOSTILE), st.one_of(st.text(max_size=30), st.integers().map(str),
                                                      st.floats(allow_nan=True, allow_infinity=True).map(repr)))
ODD_NAMES = ["value-" + "9" * 5000, "value-²", "value-0", "value--1", "value-99", "started_s-" + "9" * 400,
             "q-", "page", "action", "agree", "index", "id", "pk", "owner", "study", "key", "camera"]


@st.composite
def hostile_form(draw, valid: dict) -> dict:
    """``valid`` with drawn fields given hostile values (or several), left out, or added."""
    form = dict(valid)
    names = sorted(valid)
    for name in draw(st.lists(st.sampled_from(names), max_size=min(4, len(names)), unique=True)) if names else []:
        form[name] = draw(st.one_of(VALUE, st.lists(VALUE, min_size=2, max_size=3)))
    for name in draw(st.lists(st.sampled_from(names), max_size=2, unique=True)) if names else []:
        if draw(st.booleans()):
            form.pop(name, None)
    for name in draw(st.lists(st.sampled_from(ODD_NAMES), max_size=2, unique=True)):
        form[name] = draw(VALUE)
    return form


MODELS = (Study, System, ControlSignal, Stimulus, Participant, Question, Assignment, Rating, PlatformAction, User)


def rows() -> dict[str, list[tuple]]:
    """Every row of the MODELS' tables as stored: one plain query a table (the snapshot is
    taken twice an example, and the ORM's compiling made it a quarter of the fuzzing)."""
    snapshot = {}
    with connection.cursor() as cursor:
        for model in MODELS:
            table, key = (connection.ops.quote_name(name) for name in (model._meta.db_table, model._meta.pk.column))
            cursor.execute(f"SELECT * FROM {table} ORDER BY {key}")
            snapshot[model.__name__] = cursor.fetchall()
    return snapshot


def post_in_a_rolled_back_transaction(client: Client, url: str, form: dict) -> int:
    """Post ``form``; assert no server error and, on a refusal, no row changed. Nothing stays."""
    with transaction.atomic():
        before = rows()
        response = client.post(url, form)
        shown = {name: (str(value)[:40] + "...") if len(str(value)) > 40 else value for name, value in form.items()}
        assert response.status_code < 500, (url, shown, response.status_code)
        if 400 <= response.status_code < 500:
            assert rows() == before, (url, shown, response.status_code)
        transaction.set_rollback(True)
    return response.status_code


# --- participants ----------------------------------------------------------------------

@dataclass
class OnStep:
    """A participant's browser on a step, the step's form URL and a valid form of it."""

    client: Client
    url: str
    valid: dict
    tokens: dict = field(default_factory=dict)  # "<name>" placeholders in drawn values, by the real value


def _browser(participant: Participant) -> Client:
    """A browser holding the participant's cookie, as the entry link leaves it."""
    client = Client(raise_request_exception=False)
    client.cookies.update(_remember(HttpResponse(), participant).cookies)
    return client


def _participant(study: Study, **progress) -> Participant:
    from studyapp.participants.assignment import enrol

    participant = enrol(study, "fuzz-participant", {"PROLIFIC_PID": "fuzz-participant"})
    Participant.objects.filter(pk=participant.pk).update(**progress)
    participant.assignments.update(shown_at=timezone.now() - timezone.timedelta(hours=1))  # never answered too soon
    participant.refresh_from_db()
    return participant


def _steps_done(participant: Participant, through: str) -> dict:
    now = timezone.now()
    order = ["device_checked_at", "consented_at", "screened_at", "instructed_at", "training_done"]
    done = order[:order.index(through) + 1] if through else []
    return {name: (len(participant.training) if name == "training_done" else now) for name in done}


def on_step(step: str) -> OnStep:
    design = {"rate (side-by-side)": {"design": "side-by-side", "scale_min": 0, "scale_max": 100,
                                      "pages_per_participant": 2},
              "rate (pairwise)": {"design": "pairwise", "pages_per_participant": 4, "bad_checks": 0,
                                  "preference_strengths": 3}}.get(step, {})
    screen = {"device_check": step == "device", "min_screen_width": 800, "min_screen_height": 600}
    if step == "rate (appropriateness)":
        study = make_appropriateness_study(training_clips=0, pages_per_participant=3, **screen)
    else:
        study = make_study(**screen, **design)
    before = {"screening": "consented_at", "device": "", "consent": "device_checked_at"}
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language", text="English first?",
                            choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="age", text="Age?", kind=Question.Kind.NUMBER)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="hours", text="Hours?",
                            kind=Question.Kind.NUMBER)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="notes", text="Notes?", kind=Question.Kind.TEXT,
                            required=False)
    participant = _participant(study)
    through = before.get(step, "training_done")
    progress = _steps_done(participant, through)
    if step == "instructions":
        progress.pop("instructed_at"), progress.pop("training_done")
    if step == "practice":
        progress.pop("training_done")
    if step == "survey":
        progress["finished_at"] = timezone.now()
    Participant.objects.filter(pk=participant.pk).update(**progress)
    participant.refresh_from_db()
    unrated = participant.assignments.filter(rating__isnull=True).order_by("position")
    first = unrated.first()
    times = {"started_s": "0.1", "ended_s": "4.2", "answered_s": "5.0", "played_until_s": "4.0"}
    slots = list(unrated.filter(page=first.page).values_list("slot", flat=True)) if first else []
    valid = {
        "device": {"width": "1024", "height": "768"},
        "consent": {"agree": "yes"},
        "screening": {"q-language": "yes", "q-age": "30"},
        "instructions": {},
        "practice": {"index": "0", "value": "3"},
        "rate (single)": {"assignment": "<token>", "value": "4", **times},
        "rate (side-by-side)": {"page": "<token>", **{f"value-{slot}": "50" for slot in slots},
                                **{f"moved-{slot}": "1" for slot in slots},
                                **{f"{name}-{slot}": value for slot in slots for name, value in times.items()}},
        "rate (pairwise)": {"page": "<token>", "answer": "left", "strength": "2",
                            **{f"{name}-{slot}": value for slot in slots for name, value in times.items()}},
        "rate (appropriateness)": {"page": "<token>", "answer": "right", "strength": "1",
                                   **{f"{name}-{slot}": value for slot in slots for name, value in times.items()}},
        "survey": {"q-hours": "12", "q-notes": "fine"},
    }[step]
    url_step = step.split(" ")[0]  # every design's pages post to one step, "rate"
    return OnStep(_browser(participant), reverse(f"participant-{url_step}", args=[study.key]), valid,
                  {"<token>": first.token if first else ""})


PARTICIPANT_STEPS = ["device", "consent", "screening", "instructions", "practice", "rate (single)",
                     "rate (side-by-side)", "rate (pairwise)", "rate (appropriateness)", "survey"]


@pytest.fixture
def on(step: str) -> OnStep:
    return on_step(step)


@pytest.mark.parametrize("step", PARTICIPANT_STEPS)
@FUZZ
@given(data=st.data())
def test_hostile_values_on_a_participant_step_never_answer_500_and_a_refusal_changes_nothing(step, on, data):
    form = data.draw(hostile_form(on.valid))
    form = {name: on.tokens.get(value, value) if isinstance(value, str) else value for name, value in form.items()}
    post_in_a_rolled_back_transaction(on.client, on.url, form)


ENTRY_LINKS = {Study.Platform.PROLIFIC: {"PROLIFIC_PID": "p-1", "STUDY_ID": "s", "SESSION_ID": "x"},
               Study.Platform.MTURK: {"workerId": "w-1", "assignmentId": "a", "hitId": "h",
                                      "turkSubmitTo": "https://workersandbox.mturk.com"},
               Study.Platform.LINK: {"pid": "p-1"}}


@pytest.fixture
def open_study(platform: str) -> Study:
    return make_study(platform=platform)


@pytest.mark.parametrize("platform", ENTRY_LINKS)
@FUZZ
@given(data=st.data())
def test_hostile_entry_links_never_answer_500_and_a_refusal_enrols_nobody(platform, open_study, data):
    query = data.draw(hostile_form(ENTRY_LINKS[platform]))
    with transaction.atomic():
        before = rows()
        response = Client(raise_request_exception=False).get(reverse("participant-enter", args=[open_study.key]),
                                                              query)
        assert response.status_code < 500, (query, response.status_code)
        if response.status_code >= 400:
            assert rows() == before
        transaction.set_rollback(True)


# --- researchers -----------------------------------------------------------------------

@dataclass(frozen=True)
class Upload:
    """A file field of a valid form: its name and content (drawn forms replace either, the
    content also with what is ``hostile`` to this form in particular)."""

    name: str
    content: bytes
    hostile: st.SearchStrategy[bytes] | None = None


@dataclass
class Lab:
    """A logged-in researcher's study with every kind of row the forms touch."""

    client: Client
    study: Study
    ids: dict[str, str]  # "<name>" placeholders in the forms, by the real id
    made: dict[str, object] = field(default_factory=dict)  # what a form's valid values are made of, made once


def _zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


@pytest.fixture
def lab(client, settings, tmp_path) -> Lab:
    from studyapp.server.celery import app as celery_app
    from studyapp.server.embedded import FILESYSTEM_BROKER_URL, filesystem_broker_options

    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    settings.VAR_DIR = tmp_path / "var"
    settings.MOTION_DATA = tmp_path / "no-motion-data"  # held-out controls are refused quickly, naming it
    saved = celery_app.conf.broker_url, celery_app.conf.broker_transport_options  # queued stimuli stay here
    celery_app.conf.broker_url = FILESYSTEM_BROKER_URL
    celery_app.conf.broker_transport_options = filesystem_broker_options(tmp_path / "broker")
    owner = User.objects.create_user("researcher", is_staff=True)
    owner.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    client.force_login(owner)
    study = Study.objects.create(owner=owner, title="Gait", video_width=160, video_height=120, clips_per_participant=3)
    moglow = System.objects.create(study=study, name="MoGlow", checkpoint="model.safetensors", kind="moglow",
                                   checkpoint_digest="1" * 64,
                                   metadata={"dataset_options": DatasetOptions().to_dict(), "control": "path"})
    System.objects.create(study=study, name="NAT", role=System.Role.NATURAL, kind="natural")
    controls = [ControlSignal.objects.create(study=study, name=name, origin="synthetic", seconds=4.0,
                                             control=preset_path(name, 20.0).to_dict())
                for name in ("walk-straight", "walk-circle")]
    for control in controls:
        Stimulus.objects.create(study=study, system=moglow, control=control, content_key=control.name,
                                status=Stimulus.Status.DONE, duration_s=4.0)
    failed = Stimulus.objects.create(study=study, system=System.objects.get(study=study, name="NAT"),
                                     control=controls[1], content_key="failed", status=Stimulus.Status.FAILED)
    question = Question.objects.create(study=study, part=Question.Part.AFTER, name="notes", text="Notes?",
                                       kind=Question.Kind.TEXT)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="hours", text="Hours?", kind="number")
    other = make_study(owner_name="another-researcher")
    # Another researcher's checkpoint and submitted motion, in the store every researcher's uploads share.
    for digest, kind in ((OTHERS_CHECKPOINT, "moglow"), (OTHERS_MOTION, System.SourceKind.SUBMITTED)):
        checkpoint = f"{digest}.safetensors" if kind == "moglow" else ""
        System.objects.create(study=other, name=f"Private {kind}", checkpoint=checkpoint, checkpoint_digest=digest,
                              kind=kind, metadata={"folder": f"submitted/{digest}"})
    (settings.CHECKPOINT_ROOT / "submitted" / OTHERS_MOTION).mkdir(parents=True)
    (settings.CHECKPOINT_ROOT / f"{OTHERS_CHECKPOINT}.safetensors").write_bytes(b"their private weights")
    yield Lab(client, study, {"<moglow>": str(moglow.pk), "<control>": str(controls[0].pk), "<failed>": str(failed.pk),
                              "<question>": str(question.pk), "<other-question>": str(
                                  Question.objects.create(study=other, part="after", name="x", text="x",
                                                          kind="text").pk)})
    celery_app.conf.broker_url, celery_app.conf.broker_transport_options = saved


GOOD_RATINGS = ("participant,system,stimulus,value,scale_min,scale_max\n" +
                "".join(f"p{p},{s},{s}-{c},{(p + c) % 5 + 1},1,5\n" for p in range(4) for s in ("NAT", "MoGlow")
                        for c in range(3))).encode()


OTHERS_CHECKPOINT, OTHERS_MOTION = "2" * 64, "3" * 64
SERVER_FOLDERS = ["/", "/etc", "/root", "/no/such/folder", "..", "../..", "~", "/tmp/../etc", "no-motion-data/..",
                  "a:/etc"]
DEFINITION_SYSTEMS = {
    "another researcher's checkpoint": f"- name: M\n  role: model\n  checkpoint:\n    digest: {OTHERS_CHECKPOINT}\n"
                                       "    file: m.safetensors\n",
    "another researcher's motion": f"- name: M\n  role: model\n  submitted:\n    digest: {OTHERS_MOTION}\n",
}


def _hostile_definitions() -> st.SearchStrategy[bytes]:
    """Definitions naming what is not the researcher's: another's checkpoint or submitted
    motion by digest, server folders and takes outside them; and VALID drawn otherwise."""
    named = [VALID.replace("systems:\n", f"systems:\n{system}") for system in DEFINITION_SYSTEMS.values()]
    named += [VALID + f"- name: take\n  held_out:\n    take: {take}\n    seconds: 1\n    folders: [{folder!r}]\n"
              for folder in SERVER_FOLDERS for take in ("data/walk.bvh", "../../etc/passwd")]
    return st.one_of(st.sampled_from([text.encode() for text in named]), mutated_definition().map(str.encode))


def _bundles(lab: Lab) -> list[bytes]:
    """A real bundle (a study of NAT and two presets, exported), then the same bundle with
    its records naming what is not the importer's: a held-out take of a server folder or
    outside its folder, sampled motion of no clip (planted for other studies), another
    researcher's checkpoint without its file."""
    if "bundles" in lab.made:
        return lab.made["bundles"]
    from studyapp.bundles.pseudonyms import export_key
    from studyapp.bundles.writing import write_study_bundle
    from tests.test_hostile_bundles import members, rewritten

    folder = Path(django_settings.VAR_DIR) / "bundles"
    folder.mkdir(parents=True)
    study = create_study_from_definition(VALID, lab.study.owner, source="study.yaml")
    write_study_bundle(study, folder / "study.zip", export_key(None))
    study.delete()
    record = json.loads(members(folder / "study.zip")["study.json"])
    variants = []
    for take, folders in (("data/walk.bvh", ["/etc"]), ("../../../etc/passwd", [str(folder)]), ("x.bvh", "/etc")):
        changed = json.loads(json.dumps(record))
        changed["controls"][0] |= {"origin": "held-out", "source_clip": take, "natural": {"folders": folders}}
        variants.append({"study.json": json.dumps(changed).encode()})
    borrowed = json.loads(json.dumps(record))
    borrowed["systems"].append({**borrowed["systems"][0], "name": "Borrowed", "role": "model", "kind": "moglow",
                                "checkpoint": f"{OTHERS_CHECKPOINT}.safetensors",
                                "checkpoint_digest": OTHERS_CHECKPOINT})
    variants += [{"study.json": json.dumps(borrowed).encode()}, {f"sampled/{'a' * 64}.npz": b"PK planted motion"}]
    lab.made["bundles"] = [(folder / "study.zip").read_bytes(),
                           *(rewritten(folder / "study.zip", changes).read_bytes() for changes in variants)]
    return lab.made["bundles"]


def _bundle_form(lab: Lab) -> dict:
    valid, *hostile = _bundles(lab)
    return {"bundle": Upload("study.zip", valid, st.sampled_from(hostile)), "rerun": ""}


def _study_form(lab: Lab) -> dict:
    return {name: str(value) for name, value in study_fields().items()}


RESEARCHER_FORMS: dict[str, tuple[Callable[[Lab], str], Callable[[Lab], dict]]] = {
    "new study": (lambda lab: reverse("study-create"), _study_form),
    "study settings": (lambda lab: reverse("study-edit", args=[lab.study.pk]), _study_form),
    "checkpoint system": (lambda lab: reverse("study-systems", args=[lab.study.pk]), lambda lab: {
        "action": "checkpoint", "name": "New", "role": "model", "temperature": "1.0",
        "checkpoint": Upload("model.safetensors", b"\x10\x00\x00\x00\x00\x00\x00\x00" + b'{"a": {"b": 1}}  ')}),
    "natural system": (lambda lab: reverse("study-systems", args=[lab.study.pk]), lambda lab: {
        "action": "natural", "name": "NAT-2"}),
    "submitted motion": (lambda lab: reverse("study-systems", args=[lab.study.pk]), lambda lab: {
        "action": "motion", "name": "Lab-B", "role": "model",
        "motion": Upload("motion.zip", _zip({"walk-straight.npz": b"PK", "walk-circle.bvh": b"HIERARCHY\n"}))}),
    "video system": (lambda lab: reverse("study-systems", args=[lab.study.pk]), lambda lab: {
        "action": "videos", "name": "BAD", "role": "bad",
        "videos": Upload("bad.mp4", b"\x00\x00\x00\x18ftypisom" + b"\x00" * 64)}),
    "system edit": (lambda lab: f"/studies/{lab.study.pk}/systems/{lab.ids['<moglow>']}/edit/", lambda lab: {
        "name": "MoGlow-warm", "temperature": "0.8"}),
    "control edit": (lambda lab: f"/studies/{lab.study.pk}/controls/{lab.ids['<control>']}/edit/", lambda lab: {
        "name": "renamed"}),
    "held-out controls": (lambda lab: reverse("study-controls", args=[lab.study.pk]), lambda lab: {
        "action": "held_out", "seconds": "4", "count": "2", "lead_in": "1"}),
    "preset controls": (lambda lab: reverse("study-controls", args=[lab.study.pk]), lambda lab: {
        "action": "presets", "presets": ["sidestep-left", "stand-still"]}),
    "control file": (lambda lab: reverse("study-controls", args=[lab.study.pk]), lambda lab: {
        "action": "file", "description": Upload("path.json", b'{"segments": [{"type": "straight", "seconds": 2}]}')}),
    "label controls": (lambda lab: reverse("study-controls", args=[lab.study.pk]), lambda lab: {
        "action": "labels", "actions": ["walk"], "styles": ["normal"], "seconds": "4"}),
    "generate stimuli": (lambda lab: reverse("study-stimuli", args=[lab.study.pk]), lambda lab: {"seed": "1"}),
    "add a question": (lambda lab: reverse("study-questions", args=[lab.study.pk]), lambda lab: {
        "action": "add", "part": "before", "name": "age", "text": "Age?", "kind": "number", "required": "on",
        "minimum": "0", "maximum": "120", "whole_numbers": "on"}),
    "remove a question": (lambda lab: reverse("study-questions", args=[lab.study.pk]), lambda lab: {
        "action": "remove", "question": "<question>"}),
    "edit a question": (lambda lab: reverse("study-question-edit", args=[lab.study.pk, lab.ids["<question>"]]),
                        lambda lab: {"part": "before", "name": "remarks", "text": "Remarks?", "kind": "text",
                                     "required": "on"}),
    "move a question": (lambda lab: reverse("study-question-move", args=[lab.study.pk, lab.ids["<question>"]]),
                        lambda lab: {"direction": "down"}),
    "remove a system": (lambda lab: f"/studies/{lab.study.pk}/systems/{lab.ids['<moglow>']}/remove/", lambda lab: {}),
    "remove a control": (lambda lab: f"/studies/{lab.study.pk}/controls/{lab.ids['<control>']}/remove/",
                         lambda lab: {}),
    "retry a stimulus": (lambda lab: f"/studies/{lab.study.pk}/stimuli/{lab.ids['<failed>']}/retry/", lambda lab: {}),
    "delete the study": (lambda lab: reverse("study-delete", args=[lab.study.pk]), lambda lab: {}),
    "duplicate the study": (lambda lab: reverse("study-duplicate", args=[lab.study.pk]), lambda lab: {}),
    "the study's report": (lambda lab: reverse("study-report", args=[lab.study.pk]), lambda lab: {}),
    "open the study": (lambda lab: reverse("study-open", args=[lab.study.pk]), lambda lab: {"open": "1"}),
    "study from a definition": (lambda lab: reverse("study-from-definition"), lambda lab: {
        "definition": Upload("study.yaml", VALID.encode(), _hostile_definitions())}),
    "import a bundle": (lambda lab: reverse("study-import"), _bundle_form),
    "analysis upload": (lambda lab: reverse("analysis"), lambda lab: {
        "ratings": Upload("ratings.csv", GOOD_RATINGS), "reference": "NAT"}),
    "admin: a study": (lambda lab: "/admin/studyapp/study/add/", lambda lab: {
        **_study_form(lab), "camera": '{"azimuth": 30}'}),
    "admin: a control": (lambda lab: f"/admin/studyapp/controlsignal/{lab.ids['<control>']}/change/", lambda lab: {
        "study": str(lab.study.pk), "name": "walk-straight", "origin": "synthetic", "seconds": "4",
        "control": '{"type": "path", "fps": 20, "velocities": [[100, 0, 0], [100, 0, 0]]}'}),
}
HOSTILE_FILES = st.one_of(st.binary(max_size=600), st.sampled_from([
    b"", b"\x00" * 5000, b"\xff" * 8 + b"{}", _zip({"../../escape.npz": b"x", "a/b/walk-straight.bvh": b"\x00"}),
    b'{"segments": [{"type": "straight", "seconds": 1e400}]}', b"segments: [{type: curve, turn_rate: .nan}]",
    GOOD_RATINGS.replace(b",1,5", b",1,1e20"), GOOD_RATINGS.replace(b"NAT", b"=cmd|' /C calc'!A0")]))
# Any name a client can send (Django's test client itself refuses an empty one).
FILE_NAMES = st.sampled_from(["model.safetensors", "motion.zip", "bad.mp4", "path.json", "path.yaml", "ratings.csv",
                              " ", ".zip", "../../x.mp4", "a" * 300 + ".zip", "x\x00.json", "noextension"])


def _posted(value: object, draw) -> object:
    """A drawn form value as the client sends it: an upload becomes a file, sometimes drawn anew."""
    if isinstance(value, Upload):
        name = draw(st.one_of(st.just(value.name), FILE_NAMES))
        own = [value.hostile] if value.hostile is not None else []
        content = draw(st.one_of(st.just(value.content), HOSTILE_FILES, *own))
        return SimpleUploadedFile(name, content)
    return value


@pytest.mark.parametrize("url, valid", RESEARCHER_FORMS.values(), ids=RESEARCHER_FORMS.keys())
@FUZZ
@given(data=st.data())
def test_hostile_values_on_a_researcher_form_never_answer_500_and_a_refusal_changes_nothing(url, valid, lab, data):
    form = data.draw(hostile_form(valid(lab)))
    form = {name: _posted(lab.ids.get(value, value) if isinstance(value, str) else value, data.draw)
            for name, value in form.items()}
    post_in_a_rolled_back_transaction(lab.client, url(lab), form)


# --- the crowd platform's page ------------------------------------------------------------

TOKEN = "prolific-token-fuzz"


@dataclass
class Crowd(Lab):
    prolific: ProlificStandIn | None = None


@pytest.fixture
def crowd(client, settings) -> Crowd:
    """A Prolific study with one participant to approve and one to reject, a stand-in of
    Prolific's API (``prolific``), and the researcher's token kept; ``<calls>`` are the dry run's."""
    study = make_study(platform=Study.Platform.PROLIFIC, instructed_checks=3, stop_after_failed_checks=2)
    now = timezone.now()
    for pid, failed in (("good", 0), ("cheat", 2)):
        created = Participant.objects.create(study=study, platform_id=pid, platform_data={
            "PROLIFIC_PID": pid, "STUDY_ID": "PS1", "SESSION_ID": f"sub-{pid}"})
        Participant.objects.filter(pk=created.pk).update(started_at=now - timezone.timedelta(minutes=10),
                                                        finished_at=now, failed_checks=failed)
    submissions = {f"sub-{pid}": {"id": f"sub-{pid}", "participant_id": pid, "study_id": "PS1",
                                  "status": "AWAITING REVIEW"} for pid in ("good", "cheat")}
    with ProlificStandIn(TOKEN, submissions) as stand_in:
        settings.PROLIFIC_API_URL = stand_in.url
        client.force_login(study.owner)
        assert client.post(reverse("study-platform", args=[study.pk]), {"token": TOKEN}).status_code == 302
        plan = client.post(reverse("study-platform-dry-run", args=[study.pk]), {"kind": "decisions"}).content.decode()
        calls = re.findall(r'name="call" value="([0-9a-f]{64})" checked', plan)
        assert len(calls) == 2
        yield Crowd(client, study, {"<calls>": calls}, prolific=stand_in)


PLATFORM_FORMS: dict[str, tuple[str, Callable[[Lab], dict]]] = {
    "credentials": ("study-platform", lambda crowd: {"token": TOKEN}),
    "forget the credentials": ("study-platform", lambda crowd: {"action": "forget"}),
    "dry run of the decisions": ("study-platform-dry-run", lambda crowd: {"kind": "decisions"}),
    "dry run of bonuses": ("study-platform-dry-run", lambda crowd: {
        "kind": "bonuses", "bonuses": "good,1.50\ncheat,0.25", "reason": "thanks"}),
    "send the decisions": ("study-platform-apply", lambda crowd: {"kind": "decisions", "call": crowd.ids["<calls>"]}),
    "read back": ("study-platform-read", lambda crowd: {}),
}


@pytest.mark.parametrize("name, valid", PLATFORM_FORMS.values(), ids=PLATFORM_FORMS.keys())
@FUZZ
@given(data=st.data())
def test_hostile_values_on_the_platform_page_never_answer_500_and_a_refusal_changes_nothing(name, valid, crowd, data):
    form = data.draw(hostile_form(valid(crowd)))
    post_in_a_rolled_back_transaction(crowd.client, reverse(name, args=[crowd.study.pk]), form)


# --- the crowd platform's answers --------------------------------------------------------

# Whatever Prolific's API answers (a drawn status, content type, Retry-After and body, or
# bytes that are not HTTP), the pages that send to it or read it never answer 500, and a
# request counts as done only with an answer that says so.
ANSWER_KEYS = st.sampled_from(["id", "status", "error", "results", "_links", "next", "href", "study", "detail"])
JSON_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=20),
              st.sampled_from(["sub-good", "sub-cheat", "APPROVED", "REJECTED", "../x", "file:///etc/passwd"])),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.one_of(ANSWER_KEYS, st.text(max_size=8)),
                                                                         inner, max_size=5)),
    max_leaves=20)
ANSWER_BODIES = st.one_of(
    JSON_VALUES.map(lambda value: json.dumps(value).encode()),  # NaN and infinities as Python writes them
    st.binary(max_size=200),
    st.sampled_from([b'{"id": "sub-good", "status": "APPROVED"}', b'{"id": "sub-good", "status": "APPROVED"',
                     b"<html><body>Log in</body></html>", b"\xff\xfe{}", b"[" * 5000, b"", b"null",
                     b'{"results": [{"id": "sub-good", "status": "X"}], "_links": {"next": {"href": "http://evil/"}}}']))
ANSWER_HEADERS = st.fixed_dictionaries({}, optional={
    "Content-Type": st.sampled_from(["application/json", "application/json; charset=utf-8", "text/html",
                                     "text/plain", "application/problem+json", "", "json"]),
    "Retry-After": st.sampled_from(["abc", "-5", "nan", "inf", "0", "1", "9" * 400, "1e9", "", "Wed, 99 Foo 2026",
                                    "Tue, 01 Dec 2099 12:00:00 GMT"]),
    "Location": st.sampled_from(["http://127.0.0.1:9/x", "file:///etc/passwd", "/api/v1/x", ""])})
ANSWER_STATUSES = st.sampled_from([200, 201, 202, 204, 301, 302, 307, 400, 401, 404, 405, 429, 500, 502, 503, 599])
PLATFORM_ANSWERS = st.one_of(
    st.tuples(ANSWER_STATUSES, ANSWER_BODIES, ANSWER_HEADERS),
    st.sampled_from([Raw(b""), Raw(b"SSH-2.0-OpenSSH_9.6\r\n"), Raw(b"HTTP/1.1 200\r\n\r\n"),
                     Raw(http_answer(200, b'{"id": "sub-good", "st', length=300)),
                     Raw(http_answer(200, b'{"id": "sub-good", "status": "APPROVED"}', content_type="text/html"))]))
PLATFORM_SURFACES = {"send the decisions": "study-platform-apply", "read back": "study-platform-read"}


def confirmed_as_done(action: PlatformAction) -> bool:
    """Whether a done row's answer says that Prolific did what its key names."""
    kind, _, submission = action.key.partition(":")
    wanted = {"approve": "APPROVED", "reject": "REJECTED"}
    if kind == "read":
        statuses = action.response.get("statuses", {})
        return all(isinstance(key, str) and isinstance(value, str) and len(value) <= 40
                   for key, value in statuses.items())
    return (isinstance(action.response, dict) and action.response.get("id") == submission
            and action.response.get("status") == wanted[kind] and "error" not in action.response)


@pytest.mark.parametrize("name", PLATFORM_SURFACES.values(), ids=PLATFORM_SURFACES.keys())
@FUZZ
@given(data=st.data())
def test_hostile_platform_answers_never_answer_500_and_only_a_confirming_answer_counts_as_done(name, crowd,
                                                                                              monkeypatch, data):
    monkeypatch.setattr("studyapp.platforms.json_exchange.LONGEST_WAIT_S", 0.01)
    monkeypatch.setattr("studyapp.platforms.json_exchange.DEFAULT_WAIT_S", 0.01)
    crowd.prolific.refuse_next[:] = data.draw(st.lists(PLATFORM_ANSWERS, min_size=1, max_size=3))
    with transaction.atomic():
        response = crowd.client.post(reverse(name, args=[crowd.study.pk]),
                                     {"kind": "decisions", "call": crowd.ids["<calls>"]})
        assert response.status_code < 500, (crowd.prolific.refuse_next, response.status_code)
        done = PlatformAction.objects.filter(outcome=PlatformAction.Outcome.DONE)
        assert all(confirmed_as_done(action) for action in done), [(a.key, a.response) for a in done]
        transaction.set_rollback(True)
    crowd.prolific.refuse_next.clear()
# --- the bundle and definition uploads ---------------------------------------------------

# JSON values past every bound and of every wrong type, for any place in a bundle's records.
HOSTILE_JSON = st.sampled_from([
    None, True, False, 0, -1, 99, 4.7, 2 ** 63, 10 ** 30, 1e308, "", "+3", "٣", "３", "0x10", "1_0", "\x00",
    "a" * 70_000, "2026-02-30T10:00:00+00:00", "9999-99-99T99:99:99", "../../escape", [], {}, [[[[[]]]]],
    {"training": [], "assignments": []}])
HOSTILE_JSON_TEXTS = st.sampled_from([
    b"[" * 5000 + b"]" * 5000, b'{"a":' * 5000 + b"1" + b"}" * 5000, b"[" * 100_000, b"9" * 5000, b"NaN",
    b'{"participants": [' + b"{}," * 2_100_000 + b"{}]}", b"1e400", b'{"locked": true}', b"\xff\xfe{}", b""])
# YAML scalars that YAML 1.1 reads as numbers JSON does not write, and others no setting takes.
HOSTILE_YAML = st.sampled_from([
    "0x10", "010", "0o17", "0b11", "1_0", "1:30", "+3", "٣", "３", ".nan", "-.inf", "1e400", "9" * 5000, "~",
    "[]", "{}", "!!python/object/apply:os.system ['true']", "&a [*a, *a]", '"\\0"', "*unknown", "yes", "2026-02-30",
    "!!binary aGVsbG8=", "[" * 5000 + "]" * 5000])


def _bundled_study(owner: User) -> bytes:
    """A study with NAT and two controls, written as a bundle (nothing else to unpack)."""
    study = Study.objects.create(owner=owner, title="Bundled", video_width=160, video_height=120)
    System.objects.create(study=study, name="NAT", role=System.Role.NATURAL, kind="natural")
    for name in ("walk-straight", "walk-circle"):
        ControlSignal.objects.create(study=study, name=name, origin="synthetic", seconds=4.0,
                                     control=preset_path(name, 20.0).to_dict())
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "study.zip"
        write_study_bundle(study, path, export_key(None))
        data = path.read_bytes()
    study.delete()
    return data


def _changed_json(text: bytes, draw) -> bytes:
    """A JSON record with one drawn place (an object's member, a list's new item) given a hostile value."""
    data = json.loads(text)
    place = data
    for _ in range(draw(st.integers(0, 3))):
        inner = [value for value in (place.values() if isinstance(place, dict) else place)
                 if isinstance(value, (dict, list)) and value]
        if not inner:
            break
        place = draw(st.sampled_from(inner))
    if isinstance(place, dict):
        place[draw(st.sampled_from([*sorted(place), "owner", "id"]))] = draw(HOSTILE_JSON)
    elif isinstance(place, list):
        place.append(draw(HOSTILE_JSON))
    return json.dumps(data, ensure_ascii=False).encode()


def _hostile_bundle(valid: bytes, draw) -> bytes:
    """The bundle with one record or the manifest changed (the manifest then listing the change, mostly)."""
    with zipfile.ZipFile(io.BytesIO(valid)) as archive:
        files = {name: archive.read(name) for name in archive.namelist()}
    name = draw(st.sampled_from(["study.json", "stimuli.json", "participants.json", "plan.json", "rules.json",
                                 "study.yaml", "manifest.json"]))
    if name.endswith(".json") and draw(st.booleans()):
        files[name] = _changed_json(files[name], draw)
    else:
        files[name] = draw(st.one_of(HOSTILE_JSON_TEXTS, HOSTILE_YAML.map(lambda text: f"version: {text}\n".encode())))
    if name != "manifest.json" and draw(st.integers(0, 4)):
        manifest = json.loads(files["manifest.json"])
        manifest["files"][name] = {"sha256": entry_of(files[name]).sha256, "bytes": len(files[name])}
        files["manifest.json"] = json.dumps(manifest).encode()
    return _zip(files)


def _hostile_definition(draw) -> bytes:
    """A valid definition with one drawn setting's value hostile, or a hostile text instead."""
    lines = VALID.splitlines()
    settings_lines = [i for i, line in enumerate(lines) if ": " in line and not line.lstrip().startswith("- ")]
    if draw(st.integers(0, 5)):
        i = draw(st.sampled_from(settings_lines))
        key = lines[i].split(": ", 1)[0]
        lines[i] = f"{key}: {draw(HOSTILE_YAML)}"
        return ("\n".join(lines) + "\n").encode()
    return draw(HOSTILE_JSON_TEXTS)


@pytest.fixture
def valid_bundle(lab) -> bytes:
    return _bundled_study(lab.study.owner)


@FUZZ
@given(data=st.data())
def test_hostile_bundles_uploaded_never_answer_500_and_a_refusal_changes_nothing(lab, valid_bundle, data):
    bundle = SimpleUploadedFile("study.zip", _hostile_bundle(valid_bundle, data.draw))
    status = post_in_a_rolled_back_transaction(lab.client, reverse("study-import"), {
        "bundle": bundle, "rerun": data.draw(st.sampled_from(["", "on"]))})
    assert status in (302, 400), status


@FUZZ
@given(data=st.data())
def test_hostile_definitions_uploaded_never_answer_500_and_a_refusal_changes_nothing(lab, data):
    status = post_in_a_rolled_back_transaction(lab.client, reverse("study-from-definition"), {
        "definition": SimpleUploadedFile("study.yaml", _hostile_definition(data.draw))})
    assert status in (302, 400, 413), status  # 413: larger than a definition may be, refused before it is read
