"""Uploaded JSON and YAML read within bounds, and their values taken only as they are written.

A bundle's records and a study definition are refused, naming the file, the member and the
field, when they are nested past the bound, hold more values than a study's records do, are
larger than their kind of file may be (before any of it is read), or give a value that is
not exactly of its field's type: a rating of 4.7, ``true``, "+3", "٣" or "３" is no rating
of 3 or 4, a rating of 99 on a 1-5 scale is no rating, a time of February 30th no time, an
id longer than its column no id. YAML numbers are only those JSON writes: ``0x10`` is no 16.
"""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import pytest
from django.core.management import call_command

from studyapp.definitions import DefinitionError, create_study_from_definition
from studyapp.definitions.reading import read_definition
from studyapp.models import Rating, Study
from studyapp.server.uploads.bounded_reading import MAX_DEPTH, MAX_ITEMS
from tests.test_hostile_bundles import bundle, members, refused, rewritten  # noqa: F401 (fixtures)
from tests.test_hostile_web import UnreadBody
from tests.test_study_definition_refusals import VALID, owner  # noqa: F401 (fixtures)
from tests.test_study_researcher import files, researcher, site  # noqa: F401 (fixtures)

PAGE = "page-token-1"


def with_a_rating(bundle: Path, rating: dict | None = None, participant: dict | None = None,
                  page: dict | None = None) -> Path:
    """The bundle with one participant who rated its first clip (3 on its 1-5 scale); the
    dictionaries change the records of the rating, the participant and their page."""
    first = json.loads(members(bundle)["stimuli.json"])[0]["token"]
    page = {"position": 0, "token": PAGE, "stimulus": first, **(page or {})}
    record = {"participants": [{"platform_id": "p-1", "code": "code-1", "started_at": "2026-01-05T10:00:00+00:00",
                                "training": [], "assignments": [page], **(participant or {})}],
              "ratings": [{"assignment": page["token"], "value": 3, "answered_at": "2026-01-05T10:01:00+00:00",
                           **(rating or {})}]}
    return rewritten(bundle, {"participants.json": json.dumps(record, ensure_ascii=False).encode()})


@pytest.mark.django_db
@pytest.mark.slow
def test_a_bundle_rating_of_three_on_its_scale_imports_as_three(bundle):
    call_command("import_study", str(with_a_rating(bundle)), "--owner", "researcher")
    assert list(Rating.objects.values_list("value", flat=True)) == [3]


@pytest.mark.django_db
@pytest.mark.slow
@pytest.mark.parametrize("value, problem", [
    (99, "value 99 is outside the study's scale 1-5"), (0, "value 0 is outside the study's scale 1-5"),
    (4.7, "value must be a whole number, not 4.7"), (True, "value must be a whole number, not true"),
    ("+3", 'value must be a whole number, not "+3"'), ("٣", 'value must be a whole number, not "٣"'),
    ("３", 'value must be a whole number, not "３"'), ("3", 'value must be a whole number, not "3"')])
def test_a_bundle_rating_that_is_no_whole_number_on_the_scale_is_refused_naming_it(value, problem, bundle, settings):
    assert refused(with_a_rating(bundle, {"value": value}), settings).endswith(
        f"participants.json: ratings[0]: {problem}")


@pytest.mark.django_db
@pytest.mark.slow
@pytest.mark.parametrize("time", ["2026-02-30T10:00:00+00:00", "2026-01-05T25:00:00+00:00", "2026-13-01T10:00:00"])
def test_an_impossible_started_at_is_refused_naming_the_field(time, bundle, settings):
    assert refused(with_a_rating(bundle, participant={"started_at": time}), settings).endswith(
        f'participants.json: participants[0]: started_at must be an ISO 8601 time, got "{time}"')


@pytest.mark.django_db
@pytest.mark.slow
@pytest.mark.parametrize("field, value, kind", [
    ("ratings_per_stimulus", 4.7, "a whole number"), ("ratings_per_stimulus", True, "a whole number"),
    ("ratings_per_stimulus", "٣", "a whole number"), ("abx", 1, "true or false"), ("bad_threshold", "4", "a number"),
    ("title", 7, "text")])
def test_a_study_setting_of_another_type_is_refused_naming_the_field(field, value, kind, bundle, settings):
    record = json.loads(members(bundle)["study.json"])
    record["study"][field] = value
    changed = rewritten(bundle, {"study.json": json.dumps(record, ensure_ascii=False).encode()})
    assert refused(changed, settings).endswith(
        f"study.json: study: {field} must be {kind}, not {json.dumps(value, ensure_ascii=False)}")


@pytest.mark.django_db
@pytest.mark.slow
@pytest.mark.parametrize("changes, problem", [
    ({"page": {"token": "t" * 33}}, f"assignments[0]: its token '{'t' * 33}' is no token (1 to 32 letters"),
    ({"participant": {"code": "c" * 33}}, f"its code '{'c' * 33}' is no code (1 to 32 letters"),
    ({"participant": {"code": None}}, "its code 'None' is no code (1 to 32 letters"),
    ({"participant": {"platform_id": "p" * 101}}, "platform_id: Ensure this value has at most 100 characters")])
def test_an_id_longer_than_its_column_or_none_is_refused_not_cut(changes, problem, bundle, settings):
    assert f"participants.json: participants[0]: {problem}" in refused(with_a_rating(bundle, **changes), settings)


@pytest.mark.django_db
@pytest.mark.slow
@pytest.mark.parametrize("name", ["participants.json", "study.json", "stimuli.json", "plan.json", "manifest.json"])
def test_json_nested_thousands_deep_is_refused_naming_the_file(name, bundle, settings):
    nested = (b"[" * 100_000 + b"]" * 100_000)
    message = refused(rewritten(bundle, {name: nested}, listed=name != "manifest.json"), settings)
    assert message.endswith(f"{name}: nested more than {MAX_DEPTH} levels deep, deeper than a study's records")


@pytest.mark.django_db
@pytest.mark.slow
@pytest.mark.parametrize("text, problem", [
    (b'{"participants": [], "ratings": [], "x": ' + b"9" * 5000 + b"}", "an integer of 5000 digits"),
    (b'{"participants": [], "ratings": [], "x": NaN}', "NaN is no number JSON has"),
    (b'{"participants": [], "ratings": [], "x": 1e400}', "the number 1e400 is too large to hold")])
def test_numbers_json_cannot_hold_are_refused_naming_the_file(text, problem, bundle, settings):
    assert refused(rewritten(bundle, {"participants.json": text}), settings).endswith(
        f"participants.json: not JSON a study holds ({problem})")


def peak_megabytes(run) -> float:
    """The most memory (MB) Python held while ``run()`` ran."""
    tracemalloc.start()
    try:
        run()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak / 1e6


@pytest.mark.django_db
@pytest.mark.slow
def test_a_100_mb_participants_json_is_refused_by_its_size_before_any_of_it_is_read(bundle, settings):
    huge = rewritten(bundle, {"participants.json": b" " * 100_000_000 + b'{"participants": [], "ratings": []}'})
    messages = []
    peak = peak_megabytes(lambda: messages.append(refused(huge, settings)))
    assert messages[0].endswith("participants.json: 100 MB, over the 50 MB limit for such a file")
    assert peak < 20, peak


@pytest.mark.django_db
@pytest.mark.slow
def test_twenty_megabytes_of_empty_objects_are_refused_before_any_is_built(bundle, settings):
    """Seven million ``{}`` would be about 900 MB of dictionaries; they are counted, not built."""
    empty = b'{"participants": [' + b"{}," * 7_000_000 + b'{}], "ratings": []}'
    changed = rewritten(bundle, {"participants.json": empty})
    messages = []
    peak = peak_megabytes(lambda: messages.append(refused(changed, settings)))
    assert messages[0].endswith(f"participants.json: holds more than {MAX_ITEMS:,} values, more than a study's "
                                "records hold")
    assert peak < 150, peak
    assert not Study.objects.exists()


@pytest.mark.django_db
@pytest.mark.parametrize("written", ["0x10", "010", "0o17", "1_0", "1:30", "+3", "٣", "３", "16.0e", "0b10000",
                                     "9" * 5000])
def test_a_yaml_number_json_does_not_write_is_text_and_refused_naming_the_setting(written, owner):
    text = VALID.replace("pages_per_participant: 6", f"pages_per_participant: {written}")
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(text, owner, source="study.yaml")
    assert str(error.value) == "study.yaml:6: design.pages_per_participant must be a whole number, not text"
    assert not Study.objects.exists()


@pytest.mark.django_db
def test_an_impossible_yaml_date_is_refused_with_its_line(owner):
    text = VALID.replace("title: Gait", "title: 2026-02-30")
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(text, owner, source="study.yaml")
    assert str(error.value) == ("study.yaml:3: '2026-02-30' reads as no value (day is out of range for month): "
                                "quote it if it is text")


@pytest.mark.django_db
@pytest.mark.parametrize("written, value", [("-3", -3), ("1.5", 1.5), ("1.0e-05", 1e-05), ("2e3", 2000.0),
                                            ("0", 0)])
def test_yaml_numbers_as_json_writes_them_are_numbers(written, value):
    assert read_definition(f"version: 1\nx: {written}\n", "study.yaml").value["x"] == value


@pytest.mark.django_db
def test_a_definition_upload_over_its_limit_is_refused_before_its_body_is_read(client):
    body = UnreadBody()
    response = client.generic("POST", "/studies/new/from-definition/", b"",
                              content_type="multipart/form-data; boundary=x", CONTENT_LENGTH=str(10_000_000),
                              **{"wsgi.input": body})
    assert response.status_code == 413 and "this page takes at most 5 MB" in response.content.decode()
    assert body.bytes_read == 0
