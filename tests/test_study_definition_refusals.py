"""Hostile and mistaken study definitions: one clear error naming the file and the line,
exit status 2 from the command, 400 from the page, and nothing left behind."""

from __future__ import annotations

import io

import pytest
from django.contrib.auth.models import User
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from django.core.files.uploadedfile import SimpleUploadedFile
from django.core.management import call_command
from django.core.management.base import CommandError

from studyapp.definitions import DefinitionError, create_study_from_definition, definition_yaml
from studyapp.definitions.reading import MAX_DEFINITION_BYTES, MAX_NODES
from studyapp.models import ControlSignal, Question, Study, System, new_study_key
from tests.study_fixtures import make_study

# A study with a question, NAT and two presets: nothing it needs is outside the file.
VALID = """\
version: 1
the_study:
  title: Gait
design:
  design: pairwise
  pages_per_participant: 6
questions:
- part: after
  name: age
  text: How old are you?
  kind: number
systems:
- name: NAT
  role: natural
controls:
- name: circle
  preset: walk-circle
- name: walk-straight
  preset: walk-straight
"""


@pytest.fixture
def owner(db) -> User:
    return User.objects.create_user("researcher", password="pw-for-tests")


def nothing_left() -> bool:
    return not (Study.objects.exists() or System.objects.exists() or ControlSignal.objects.exists()
                or Question.objects.exists())


def refused(text: str | bytes, owner: User) -> DefinitionError:
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(text, owner, source="study.yaml")
    assert nothing_left()
    return error.value


@pytest.mark.django_db
def test_a_valid_definition_makes_a_closed_study_of_it(owner):
    study = create_study_from_definition(VALID, owner, source="study.yaml")
    assert (study.title, study.design, study.pages_per_participant, study.is_open) == ("Gait", "pairwise", 6, False)
    assert study.scale_min == 1 and study.bad_threshold == 4.0  # left out: the study page's defaults
    assert sorted(study.controls.values_list("name", "export_id")) == [("circle", "walk-circle"),
                                                                      ("walk-straight", "walk-straight")]
    assert study.questions.get().name == "age" and study.systems.get().role == "natural"


@pytest.mark.django_db
def test_text_of_several_lines_is_a_block_and_comes_back_the_same(owner):
    study = create_study_from_definition(VALID, owner, source="study.yaml")
    Study.objects.filter(pk=study.pk).update(instructions="Watch each clip.\r\nThen rate it.")  # as a browser sends it
    study.refresh_from_db()
    text = definition_yaml(study)
    assert "  instructions: |-\n    Watch each clip.\n    Then rate it.\n" in text
    copy = create_study_from_definition(text, owner, source="study.yaml")
    assert copy.instructions == "Watch each clip.\nThen rate it." and definition_yaml(copy) == text


def replaced(old: str, new: str) -> str:
    assert old in VALID
    return VALID.replace(old, new)


MISTAKES = [
    ("not yaml", "version: 1\nthe_study: {title: [Gait\n", 3, "not valid YAML"),
    ("a list at the top", "- version: 1\n", 1, "a study definition is a mapping of settings, not a list"),
    ("text at the top", "just a title\n", 1, "a study definition is a mapping of settings, not a str"),
    ("an unknown section", VALID + "extras: {}\n", 20, "unknown section 'extras'"),
    ("an unknown setting", replaced("  pages_per_participant: 6", "  pages_per_participant: 6\n  pages: 6"), 7,
     "unknown setting 'pages' in design"),
    ("a setting in another section", replaced("  title: Gait", "  title: Gait\n  abx: true"), 4,
     "unknown setting 'abx' in the_study"),
    ("text for a number", replaced("pages_per_participant: 6", "pages_per_participant: six"), 6,
     "design.pages_per_participant must be a whole number, not text"),
    ("a fraction for a whole number", replaced("pages_per_participant: 6", "pages_per_participant: 6.5"), 6,
     "must be a whole number, not a number"),
    ("a number for text", replaced("title: Gait", "title: 1984"), 3, "the_study.title must be text, not a whole number"),
    ("a list for a section", replaced("the_study:\n  title: Gait", "the_study: [Gait]"), 2,
     "the_study must be a mapping of settings, not a list"),
    ("a bound of the study page", replaced("pages_per_participant: 6", "pages_per_participant: 1000"), 6,
     "design.pages_per_participant: must be a number from 0 to 100"),
    ("a design's own check", replaced("pages_per_participant: 6", "pages_per_participant: 1"), 6,
     "leave room for rated pages"),
    ("an unknown design", replaced("design: pairwise", "design: ranking"), 5, "ranking is not one of the available"),
    ("a camera past its bound", VALID + "video_and_camera:\n  camera: {distance: 1.0e+6}\n", 21,
     "'distance' must be a number from 20 to 10000"),
    ("NaN", replaced("pages_per_participant: 6", "pages_per_participant: .nan"), 6, "numbers must be finite, not .nan"),
    ("infinity", VALID + "attention_checks_and_early_answers: {bad_threshold: -.inf}\n", 20,
     "numbers must be finite, not -.inf"),
    ("a key that is a number", replaced("  title: Gait", "  title: Gait\n  7: seven"), 4,
     "a key must be a name (text), not '7'"),
    ("a control character", replaced("title: Gait", "title: Ga\x1fit"), 3,
     "not valid YAML: the character '\\x1f' cannot be in a YAML file"),
    ("a key twice", replaced("  title: Gait", "  title: Gait\n  title: Walk"), 4, "'title' is given twice"),
    ("a date", replaced("title: Gait", "title: 2024-01-01"), 3, "reads as a date: quote it if it is text"),
    ("a Python object", replaced("title: Gait", "title: !!python/object:os.system [ls]"), 3, "not a plain YAML value"),
    ("another version", replaced("version: 1", "version: 2"), 1, "version must be 1"),
    ("a question the questions page refuses", replaced("  kind: number", "  kind: choice\n  choices: [only one]"), 12,
     "a choice question needs at least two choices"),
    ("a question's unknown setting", replaced("  kind: number", "  kind: number\n  colour: red"), 12,
     "unknown setting 'colour' in questions[0]"),
    ("a checkpoint not in the store", replaced("- name: NAT\n  role: natural", f"- name: M\n  role: model\n  checkpoint:\n"
                                               f"    digest: {'ab' * 32}\n    file: m.safetensors"), 16,
     f"no checkpoint {'ab' * 32} in the checkpoint store"),
    ("a digest that is a path", replaced("- name: NAT\n  role: natural", "- name: M\n  role: model\n  checkpoint:\n"
                                         "    digest: ../../etc/passwd\n    file: m.safetensors"), 16,
     "must be a SHA-256 digest (64 hexadecimal digits)"),
    ("a model without motion", replaced("  role: natural", "  role: model"), 14, "a model system needs a checkpoint"),
    ("uploaded videos", replaced("  role: natural", "  role: bad\n  videos: [bad.mp4]"), 15,
     "a system of uploaded videos cannot be made from a definition"),
    ("an unknown preset", replaced("preset: walk-circle", "preset: moonwalk"), 17, "unknown control preset 'moonwalk'"),
    ("a control of two kinds", replaced("  preset: walk-circle", "  preset: walk-circle\n  labels: {}"), 16,
     "give one of preset, path, labels, held_out, not preset and labels"),
    ("a path of the wrong shape", replaced("  preset: walk-circle", "  path: {fps: 20, velocities: [[1, 2], [3, 4]]}"),
     17, "not a path (path control needs shape (frames >= 2, 3)"),
    ("a path at another frame rate", replaced("  preset: walk-circle",
                                              "  path: {fps: 30, velocities: [[1, 0, 0], [1, 0, 0]]}"), 17,
     "the path is at 30 fps and the study's motion at 20 fps"),
    ("two controls of one name", replaced("- name: walk-straight", "- name: circle"), 18,
     "this study already has a control named 'circle'"),
    ("a system name past its column", replaced("- name: NAT", "- name: " + "N" * 61), 13,
     "systems[0]: name Ensure this value has at most 60 characters (it has 61)"),
    ("a control name past its column", replaced("- name: circle", "- name: " + "c" * 101), 16,
     "controls[0]: name Ensure this value has at most 100 characters (it has 101)"),
    ("a NUL character", replaced("title: Gait", 'title: "Ga\\0it"'), 3, "holds a NUL character"),
    ("an export id that is no file name", replaced("  preset: walk-circle", "  preset: walk-circle\n  export_id: ../x"),
     18, "an export id is a plain file name"),
]


@pytest.mark.parametrize("text, line, message", [case[1:] for case in MISTAKES], ids=[case[0] for case in MISTAKES])
def test_a_mistaken_definition_is_one_error_with_its_line_and_leaves_nothing(owner, text, line, message):
    error = refused(text, owner)
    assert f"study.yaml:{line}: " in str(error) and message in str(error), str(error)
    assert "\n" not in str(error)


@pytest.mark.django_db
def test_empty_sections_and_lists_are_empty(owner):
    study = create_study_from_definition("version: 1\nthe_study: {title: Gait}\ndesign:\nquestions:\nsystems:\n", owner,
                                         source="study.yaml")
    assert study.design == "single" and not study.questions.exists() and not study.systems.exists()


def test_a_document_over_the_size_limit_is_refused_before_it_is_read(owner):
    error = refused("version: 1\n" + "#" * MAX_DEFINITION_BYTES, owner)
    assert "MB is over the 4 MB a study definition may be" in str(error)


def test_deep_nesting_is_refused_however_deep(owner):
    for depth in (50, 100_000):
        error = refused("version: 1\nthe_study: " + "[" * depth + "]" * depth + "\n", owner)
        assert "nested" in str(error) and "deep" in str(error)


def test_aliases_that_repeat_values_past_the_limit_are_refused(owner):
    laughs = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    laughs += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
    error = refused("version: 1\n" + "\n".join(laughs) + "\n", owner)
    assert f"more than {MAX_NODES:,} values" in str(error)


def test_text_that_is_not_utf8_is_refused(owner):
    assert "not UTF-8 text (byte 18)" in str(refused(b"version: 1\ntitle: \xff\xfe\n", owner))


def test_an_empty_file_is_refused(owner):
    assert "the file is empty" in str(refused("# nothing\n", owner))


# --- the commands -----------------------------------------------------------------

@pytest.mark.django_db
def test_create_study_from_a_mistaken_file_exits_with_status_2_and_one_line(owner, tmp_path):
    path = tmp_path / "study.yaml"
    path.write_text(replaced("pages_per_participant: 6", "pages_per_participant: 1000"))
    with pytest.raises(CommandError) as error:
        call_command("create_study", "researcher", "--from", str(path))
    assert error.value.returncode == 2 and str(error.value).startswith(f"{path}:6: design.pages_per_participant")
    assert nothing_left()
    with pytest.raises(CommandError) as error:
        call_command("create_study", "researcher", "--from", str(tmp_path / "missing.yaml"))
    assert error.value.returncode == 2 and "missing.yaml: no such file" in str(error.value)
    with pytest.raises(CommandError) as error:
        call_command("create_study", "researcher", "Another title", "--from", str(path), "--design", "pairwise")
    assert error.value.returncode == 2 and "TITLE, --design: the definition file sets these" in str(error.value)


@pytest.mark.django_db
def test_describe_study_to_a_folder_or_into_a_missing_one_exits_with_status_2_and_writes_nothing(owner, tmp_path):
    out = io.StringIO()
    call_command("create_study", "researcher", "A title", stdout=out)
    study = out.getvalue().strip()
    for target in (tmp_path, tmp_path / "missing" / "study.yaml"):
        with pytest.raises(CommandError) as error:
            call_command("describe_study", study, "--out", str(target))
        assert error.value.returncode == 2 and str(error.value) == f"{target}: give a file in an existing folder"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.django_db
def test_create_study_keeps_its_options(owner):
    out = io.StringIO()
    call_command("create_study", "researcher", "Sliders", "--design", "side-by-side", "--pages", "5", stdout=out)
    study = Study.objects.get(pk=int(out.getvalue()))
    assert (study.title, study.scale_min, study.scale_max) == ("Sliders", 0, 100)
    with pytest.raises(CommandError) as error:
        call_command("create_study", "researcher")
    assert error.value.returncode == 2 and "give the study's TITLE, or a definition file with --from" in str(error.value)


@pytest.mark.django_db
def test_describe_study_names_a_study_that_is_not_there(owner):
    with pytest.raises(CommandError) as error:
        call_command("describe_study", "no-such-key")
    assert error.value.returncode == 2 and "no study with the id or key 'no-such-key'" in str(error.value)


def test_new_study_keys_never_begin_with_a_dash_which_a_command_line_reads_as_an_option(monkeypatch):
    drawn = iter(["-Zk3vQ0aLmNo", "Zk3vQ0aLmNo-"])
    monkeypatch.setattr("studyapp.models.secrets.token_urlsafe", lambda nbytes: next(drawn))
    assert new_study_key() == "Zk3vQ0aLmNo-"


@pytest.mark.django_db
def test_describe_study_takes_an_older_key_that_begins_with_a_dash_after_two_dashes(owner):
    study = create_study_from_definition(VALID, owner, source="study.yaml")
    Study.objects.filter(pk=study.pk).update(key="-older-key1")
    printed = io.StringIO()
    call_command("describe_study", "--", "-older-key1", stdout=printed)
    assert printed.getvalue() == definition_yaml(study)


# --- the pages --------------------------------------------------------------------

@pytest.mark.django_db
def test_the_study_page_offers_its_definition_to_its_owner_only(client, owner):
    study = create_study_from_definition(VALID, owner, source="study.yaml")
    url = f"/studies/{study.pk}/definition.yaml"
    assert client.get(url).status_code == 302  # to the login page
    other = User.objects.create_user("other")
    client.force_login(other)
    assert client.get(url).status_code == 404
    client.force_login(owner)
    assert url in client.get(f"/studies/{study.pk}/monitor/").content.decode()
    response = client.get(url)
    assert response.status_code == 200 and response["Content-Type"].startswith("application/yaml")
    assert response["Content-Disposition"] == f'attachment; filename="study-{study.pk}.yaml"'
    assert response.content.decode() == definition_yaml(study)


@pytest.mark.django_db
def test_a_study_whose_rows_cannot_be_read_has_no_definition_and_says_which_row(client, owner):
    study = make_study(owner_name="researcher", controls=1)  # its control is stored as {"type": "path"}
    client.force_login(owner)
    response = client.get(f"/studies/{study.pk}/definition.yaml", follow=True)
    assert response.redirect_chain[-1][0] == f"/studies/{study.pk}/monitor/"
    assert "No definition: control signal &#x27;control-0&#x27;" in response.content.decode()
    with pytest.raises(CommandError) as error:
        call_command("describe_study", str(study.pk))
    assert error.value.returncode == 2 and "its control is no control description" in str(error.value)


@pytest.mark.django_db
def test_a_study_is_made_from_an_uploaded_definition(client, owner):
    client.force_login(owner)
    page = client.get("/studies/new/from-definition/")
    assert page.status_code == 200 and "csrfmiddlewaretoken" in page.content.decode()
    response = client.post("/studies/new/from-definition/",
                           {"definition": SimpleUploadedFile("gait.yaml", VALID.encode())})
    study = Study.objects.get()
    assert response.status_code == 302 and response["Location"] == f"/studies/{study.pk}/"
    assert study.owner == owner and study.title == "Gait" and study.controls.count() == 2


@pytest.mark.django_db
def test_a_refused_upload_lists_each_problem_with_its_line_and_keeps_nothing(client, owner):
    client.force_login(owner)
    mistaken = replaced("  title: Gait", "  title: 7\n  colour: red")
    response = client.post("/studies/new/from-definition/",
                           {"definition": SimpleUploadedFile("gait.yaml", mistaken.encode())})
    page = response.content.decode()
    assert response.status_code == 400 and nothing_left()
    assert "<li>gait.yaml:3: the_study.title must be text, not a whole number</li>" in page
    assert "<li>gait.yaml:4: unknown setting &#x27;colour&#x27; in the_study" in page
    assert page.index('id="refused"') < page.index('enctype="multipart/form-data"')
    huge = SimpleUploadedFile("huge.yaml", b"#" * (MAX_DEFINITION_BYTES + 1))
    response = client.post("/studies/new/from-definition/", {"definition": huge})
    assert response.status_code == 400 and "the limit is 4 MB" in response.content.decode() and nothing_left()


@pytest.mark.django_db
def test_the_upload_needs_a_login_and_csrf(owner):
    from django.test import Client

    assert Client().get("/studies/new/from-definition/").status_code == 302
    strict = Client(enforce_csrf_checks=True)
    strict.force_login(owner)
    response = strict.post("/studies/new/from-definition/", {"definition": SimpleUploadedFile("g.yaml", VALID.encode())})
    assert response.status_code == 403 and nothing_left()


# --- fuzzed definitions -------------------------------------------------------------

HOSTILE_VALUES = [".nan", "-.inf", "1e400", "9" * 400, "-1", "0", "~", "[]", "{}", "[[[", "'", '"\\0"', "!!binary AA==",
                  "!!set {a}", "*nowhere", "&a x", "2024-01-01", "yes", "é" * 300, "<<: {a: 1}", "? [a]", "- -", ": :"]


@st.composite
def mutated_definition(draw) -> str:
    """VALID with values replaced, lines dropped, repeated or indented otherwise."""
    lines = VALID.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["value", "drop", "repeat", "indent"]))
        if action == "value":
            key = lines[i].split(":", 1)[0] if ":" in lines[i] else lines[i]
            token = draw(st.one_of(st.sampled_from(HOSTILE_VALUES), st.text(max_size=12),
                                   st.floats(allow_nan=True, allow_infinity=True).map(repr)))
            lines[i] = f"{key}: {token}"
        elif action == "drop" and len(lines) > 1:
            del lines[i]
        elif action == "repeat":
            lines.insert(i, lines[i])
        else:
            lines[i] = " " * draw(st.integers(0, 5)) + lines[i].lstrip()
    return "\n".join(lines) + "\n"


@pytest.mark.django_db
@settings(max_examples=100, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(text=mutated_definition())
def test_a_fuzzed_definition_makes_a_study_or_one_error_and_nothing(owner, text):
    try:
        study = create_study_from_definition(text, owner, source="study.yaml")
    except DefinitionError as error:
        assert str(error).startswith("study.yaml") and "\n" not in str(error)
        assert nothing_left()
    else:
        assert definition_yaml(study).startswith("# A study definition")
        study.delete()
