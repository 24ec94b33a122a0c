"""The control file and the rules file a researcher uploads, read within bounds.

A control file on the controls page and the rules.json of a bundle imported as a rerun
(which the study's report later hands to the analysis) are refused with a 400 naming the
file and what is wrong when they are nested thousands deep, hold an integer of thousands
of digits or are larger than their kind of file may be; in a control file's YAML, numbers
are only those JSON writes: ``0x10`` is no speed of 16. A valid file still goes through.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from django.core.files.uploadedfile import SimpleUploadedFile

from studyapp.models import PreviousRun, Study
from studyapp.server.uploads.bounded_reading import MAX_DEPTH
from tests.test_hostile_bundles import bundle, members, rewritten  # noqa: F401 (fixtures)
from tests.test_study_researcher import files, new_study, researcher, site, upload_checkpoint  # noqa: F401 (fixtures)

pytestmark = pytest.mark.django_db

NESTED = b"[" * 5000 + b"]" * 5000
LONG_INTEGER = b"9" * 5000


@pytest.fixture
def path_study(client, researcher, site, files) -> Study:
    """A study whose checkpoint is controlled by paths, on whose controls page files are uploaded."""
    study = new_study(researcher)
    assert upload_checkpoint(client, study, files.good.read_bytes()).status_code == 302
    return study


def post_control_file(client, study: Study, name: str, data: bytes):
    return client.post(f"/studies/{study.pk}/controls/", {"action": "file",
                                                          "description": SimpleUploadedFile(name, data)})


def refused_page(response) -> str:
    page = response.content.decode()
    assert response.status_code == 400 and "Traceback" not in page
    return page


def test_a_valid_control_file_still_adds_its_paths(client, path_study):
    yaml_file = b"- segments: [{type: straight, speed: 100, seconds: 1.5}]\n"
    assert post_control_file(client, path_study, "walk.yaml", yaml_file).status_code == 302
    assert post_control_file(client, path_study, "run.json",
                             b'{"segments": [{"type": "straight", "speed": 200, "seconds": 1}]}').status_code == 302
    assert set(path_study.controls.values_list("name", flat=True)) == {"walk-0", "run-0"}


@pytest.mark.parametrize("name, data", [("deep.json", NESTED), ("deep.yaml", NESTED),
                                        ("deep.yaml", b"".join(b"  " * i + b"- \n" for i in range(100)))])
def test_a_control_file_nested_thousands_deep_is_refused_naming_it(client, path_study, name, data):
    page = refused_page(post_control_file(client, path_study, name, data))
    assert f"{name}: nested" in page
    assert not path_study.controls.exists()


@pytest.mark.parametrize("name, data, problem", [
    ("long.json", b'{"segments": [{"type": "straight", "speed": ' + LONG_INTEGER + b', "seconds": 1}]}',
     "long.json: not JSON a study holds (an integer of 5000 digits)"),
    ("long.yaml", b"segments: [{type: straight, speed: " + LONG_INTEGER + b", seconds: 1}]\n",
     "long.yaml: path 0: segment 0: &#x27;speed&#x27; must be a number, got &#x27;9999")])
def test_a_control_file_integer_of_thousands_of_digits_is_refused_naming_it(client, path_study, name, data, problem):
    assert problem in refused_page(post_control_file(client, path_study, name, data))
    assert not path_study.controls.exists()


@pytest.mark.parametrize("speed", ["0x10", "1_0", "+3"])
def test_a_yaml_number_json_does_not_write_is_text_and_refused_naming_the_setting(client, path_study, speed):
    page = refused_page(post_control_file(client, path_study, "speed.yaml",
                                          f"segments: [{{type: straight, speed: {speed}, seconds: 1}}]\n".encode()))
    assert f"speed.yaml: path 0: segment 0: &#x27;speed&#x27; must be a number, got &#x27;{speed}&#x27;" in page
    assert not path_study.controls.exists()


def test_an_oversized_control_file_is_refused_naming_it(client, path_study):
    data = b'{"segments": [{"type": "stand", "seconds": 1}], "note": "' + b"x" * 1_000_000 + b'"}'
    assert "big.json: 1.0 MB is over the 1 MB limit" in refused_page(post_control_file(client, path_study, "big.json",
                                                                                        data))
    assert not path_study.controls.exists()


def import_rerun(client, bundle: Path, rules: bytes | None = None):
    changed = rewritten(bundle, {"rules.json": rules}) if rules is not None else bundle
    return client.post("/studies/import/", {"bundle": SimpleUploadedFile("study.zip", changed.read_bytes()),
                                            "rerun": "on"})


@pytest.mark.slow
def test_a_rerun_bundle_with_valid_rules_still_imports_them(client, researcher, bundle):
    assert import_rerun(client, bundle).status_code == 302
    assert json.loads(PreviousRun.objects.get().rules_json) == json.loads(members(bundle)["rules.json"])


@pytest.mark.slow
@pytest.mark.parametrize("rules, problem", [
    (NESTED, f"rules.json: nested more than {MAX_DEPTH} levels deep"),
    (b'{"bad_at_or_above": ' + LONG_INTEGER + b"}", "rules.json: not JSON a study holds (an integer of 5000 digits)"),
    (b'{"bad_at_or_above": "high"}', "rules.json: bad_at_or_above must be a float, not &#x27;high&#x27;")])
def test_a_rerun_bundle_with_rules_the_analysis_cannot_read_is_refused_naming_them(client, researcher, bundle, rules,
                                                                                    problem):
    assert problem in refused_page(import_rerun(client, bundle, rules))
    assert not Study.objects.exists() and not PreviousRun.objects.exists()


@pytest.mark.slow
def test_an_oversized_rules_file_is_refused_naming_it(client, researcher, bundle, settings):
    settings.MAX_RECORD_UPLOAD_BYTES = 200_000  # more than the small study's other records hold
    rules = json.dumps({"natural_system": "NAT" + " " * 300_000}).encode()
    assert "rules.json" in refused_page(import_rerun(client, bundle, rules))
    assert not Study.objects.exists()
