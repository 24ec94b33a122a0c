"""Hostile study bundles: each is refused by ``import_study`` with one line naming the file
and the problem, exit status 2, and nothing left behind: no row in the database and no file
(not even a temporary one) in the checkpoint store, the media or the sampled motion.

The bundle taken apart here is a real export: a tiny MoGlow with two preset paths, NAT, a
question, its clips rendered, with their videos, and an uploaded BAD video. Each test changes it in one way,
writing a manifest that lists the change where the change is not the manifest's lie.
"""

from __future__ import annotations

import hashlib
import io
import json
import struct
import zipfile
from pathlib import Path

import pytest
from django.core.files import File
from django.core.management import call_command
from django.core.management.base import CommandError

from studyapp.bundles.manifest import entry_of
from studyapp.bundles.pseudonyms import export_key
from studyapp.bundles.writing import write_study_bundle
from studyapp.models import ControlSignal, Question, Stimulus, Study, System
from studyapp.preregistration.contents import canonical_json
from studyapp.stimuli.clips import plan_stimuli, render_stimulus
from studyapp.stimuli.controls import add_preset_controls
from studyapp.stimuli.systems import add_checkpoint_system, add_natural_system, add_video_system
from tests.test_study_researcher import files, new_study, researcher, site  # noqa: F401 (fixtures)

pytestmark = [pytest.mark.django_db, pytest.mark.slow]


def small_study(researcher, files) -> Study:
    """A tiny MoGlow on two preset paths, NAT, an uploaded BAD video and a question, its clips rendered."""
    study = new_study(researcher)
    with File(files.good.open("rb"), name="moglow.safetensors") as upload:
        add_checkpoint_system(study, "MoGlow", upload)
    add_natural_system(study)
    with File(files.video.open("rb"), name="bad.mp4") as video:
        add_video_system(study, "BAD", [video])
    add_preset_controls(study, ["walk-circle", "stand-still"])
    Question.objects.create(study=study, part="after", name="age", text="Your age?", kind="number")
    for stimulus in plan_stimuli(study)[0]:
        Stimulus.objects.filter(pk=stimulus.pk).update(status="done", duration_s=render_stimulus(stimulus))
    return study


@pytest.fixture
def bundle(researcher, site, files, tmp_path, settings) -> Path:
    """A study's bundle, exported; then the study and its files are gone and the media,
    checkpoint and var folders point somewhere empty, as on another server."""
    path = tmp_path / "study.zip"
    write_study_bundle(small_study(researcher, files), path, export_key(None), with_videos=True)
    Study.objects.all().delete()
    root = tmp_path / "another-server"
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT, settings.VAR_DIR = root / "media", root / "checkpoints", root / "var"
    return path


def members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def rewritten(path: Path, changes: dict[str, bytes | None], listed: bool = True) -> Path:
    """The bundle with ``changes`` (None removes a file); with ``listed`` its manifest lists them as they are."""
    files = {**members(path), **changes}
    files = {name: data for name, data in files.items() if data is not None}
    if listed:
        manifest = json.loads(files["manifest.json"])
        manifest["files"] = {name: {"sha256": entry_of(data).sha256, "bytes": len(data)}
                             for name, data in files.items() if name != "manifest.json"}
        files["manifest.json"] = json.dumps(manifest).encode()
    out = path.with_name(f"changed-{path.name}")
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return out


def files_under(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")) if root.exists() else []


def refused(path: Path, settings) -> str:
    """``import_study``'s one line for ``path``, checking that it exits 2 and leaves nothing behind."""
    rows = [model.objects.count() for model in (Study, System, ControlSignal, Stimulus, Question)]
    with pytest.raises(CommandError) as error:
        call_command("import_study", str(path), "--owner", "researcher", stdout=io.StringIO())
    assert error.value.returncode == 2
    message = str(error.value)
    assert "\n" not in message and "Traceback" not in message
    assert [model.objects.count() for model in (Study, System, ControlSignal, Stimulus, Question)] == rows
    for root in (settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT, settings.VAR_DIR / "sampled"):
        assert [name for name in files_under(Path(root)) if not Path(root, name).is_dir()] == [], root
    return message


def test_the_unchanged_bundle_imports_with_its_files(bundle, settings):
    call_command("import_study", str(bundle), "--owner", "researcher", stdout=io.StringIO())
    study = Study.objects.get()
    # MoGlow's two presets and the uploaded video (NAT has no held-out control to show)
    assert study.stimuli.filter(status="done").count() == 2 + 1
    assert all(stimulus.video_path().is_file() for stimulus in study.stimuli.all())
    assert len(files_under(Path(settings.CHECKPOINT_ROOT))) == 1
    recorded = next(s for s in json.loads(members(bundle)["stimuli.json"]) if s["system"] == "BAD")
    assert study.systems.get(name="BAD").stimuli.get().content_key == recorded["content_key"]


def test_bad_yaml_in_the_definition_is_refused_with_its_line(bundle, settings):
    message = refused(rewritten(bundle, {"study.yaml": b"format: 1\ntitle: [unclosed\n"}), settings)
    assert message.endswith("changed-study.zip: study.yaml:3: not valid YAML: expected ',' or ']', but got "
                            "'<stream end>'")


def test_a_definition_that_describes_another_study_is_refused(bundle, settings):
    text = members(bundle)["study.yaml"].decode().replace("Locomotion", "Something else")
    message = refused(rewritten(bundle, {"study.yaml": text.encode()}), settings)
    assert message.startswith(f"{bundle.with_name('changed-study.zip')}: study.yaml:") and "Something else" in message


def test_a_file_that_differs_from_the_manifest_is_refused(bundle, settings):
    ratings = members(bundle)["ratings.csv"] + b"x"
    assert "ratings.csv: its SHA-256 or size differs" in refused(rewritten(bundle, {"ratings.csv": ratings},
                                                                           listed=False), settings)


def test_a_checkpoint_swapped_along_with_its_manifest_entry_is_refused(bundle, settings):
    name = next(n for n in members(bundle) if n.startswith("checkpoints/"))
    damaged = bytearray(members(bundle)[name])
    damaged[-8:] = b"\x00" * 8  # the last tensor's bytes: the tensors no longer match their digest
    assert name in refused(rewritten(bundle, {name: bytes(damaged)}), settings)


def test_a_file_missing_from_or_not_listed_in_the_manifest_is_refused(bundle, settings):
    assert "notes.txt: not listed in manifest.json" in refused(
        rewritten(bundle, {"notes.txt": b"added later"}, listed=False), settings)
    assert "rules.json: listed in manifest.json but not in the bundle" in refused(
        rewritten(bundle, {"rules.json": None}, listed=False), settings)


@pytest.mark.parametrize("name", ["../outside.txt", "/tmp/outside.txt", "stimuli/../../outside.txt"])
def test_a_member_named_outside_the_bundle_is_refused(name, bundle, settings, tmp_path):
    message = refused(rewritten(bundle, {name: b"zip slip"}), settings)
    assert "a member name must be a relative path without '..'" in message
    assert not (tmp_path / "outside.txt").exists() and not Path("/tmp/outside.txt").exists()


def test_ten_thousand_files_are_refused(bundle, settings):
    many = {f"extra/{i}.txt": b"" for i in range(10_000)}
    assert "the zip holds 10" in refused(rewritten(bundle, many), settings)


def claimed_size(path: Path, name: str, size: int) -> Path:
    """The zip with ``name``'s central-directory entry claiming ``size`` bytes unpacked (nothing of it written)."""
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo(name)
    position = data.find(b"PK\x01\x02")
    while position != -1:
        name_length = struct.unpack_from("<H", data, position + 28)[0]
        if data[position + 46:position + 46 + name_length].decode() == info.filename:
            struct.pack_into("<I", data, position + 24, size)
            break
        position = data.find(b"PK\x01\x02", position + 4)
    assert position != -1
    out = path.with_name("claimed.zip")
    out.write_bytes(bytes(data))
    return out


def test_a_member_claiming_two_gigabytes_is_refused_before_anything_is_read(bundle, settings):
    message = refused(claimed_size(bundle, "ratings.csv", 2_000_000_000), settings)
    assert "the zip unpacks to 2e+03 MB, over the 1000 MB limit" in message


def test_a_member_that_inflates_past_its_kind_limit_or_its_declared_size_is_refused(bundle, settings):
    settings.MAX_RECORD_UPLOAD_BYTES = 1_000_000
    big = rewritten(bundle, {"participants.json": b" " * 2_000_000})  # deflates to a few kB
    assert "participants.json: 2 MB, over the 1 MB limit for such a file" in refused(big, settings)
    settings.MAX_RECORD_UPLOAD_BYTES = 50_000_000
    lying = claimed_size(rewritten(bundle, {"participants.json": b" " * 2_000_000}), "participants.json", 1000)
    assert "participants.json: a damaged zip member (Bad CRC-32" in refused(lying, settings)  # read to 1000 bytes


def test_a_plan_changed_after_it_was_locked_or_not_a_plan_is_refused(bundle, settings):
    locked = {"locked": True, "plan": {"design": "single"}, "sha256": "0" * 64,
              "locked_at": "2026-01-01T00:00:00+00:00", "deviations": []}
    assert refused(rewritten(bundle, {"plan.json": json.dumps(locked).encode()}), settings).endswith(
        "plan.json: the plan does not match its SHA-256: it was changed after it was locked")
    for hostile in ([], {"locked": "yes"}, {**locked, "extra": 1}, {**locked, "deviations": [{"at": 1}]}):
        assert "plan.json: " in refused(rewritten(bundle, {"plan.json": json.dumps(hostile).encode()}), settings)


def test_a_record_that_is_not_utf8_text_or_not_json_is_refused_naming_it(bundle, settings):
    assert refused(rewritten(bundle, {"plan.json": b'{"locked": "\xe9"}'}), settings).endswith(
        "plan.json: not UTF-8 text ('utf-8' codec can't decode byte 0xe9 in position 12: invalid "
        "continuation byte)")
    assert "plan.json: not JSON (Expecting value" in refused(rewritten(bundle, {"plan.json": b"locked"}), settings)


def test_a_plan_rehashed_without_what_a_plan_holds_is_refused(bundle, settings):
    """The SHA-256 proves nothing against someone who recomputes it: the plan must also read as a plan."""
    def locked(plan: dict, deviations: list) -> bytes:
        sha256 = hashlib.sha256(canonical_json(plan).encode()).hexdigest()
        return json.dumps({"locked": True, "plan": plan, "sha256": sha256, "locked_at": "2026-01-01T00:00:00+00:00",
                           "deviations": deviations}).encode()

    plan = {"design": {"name": "single", "settings": {}}}  # no rules, systems, analysis, participants
    assert "plan.json: the plan lacks or garbles what a plan holds" in refused(
        rewritten(bundle, {"plan.json": locked(plan, [])}), settings)
    too_long = {"at": "2026-01-02T00:00:00+00:00", "field": "x" * 300, "old": 1, "new": 2, "recorded": True}
    assert "plan.json: " in refused(rewritten(bundle, {"plan.json": locked(plan, [too_long])}), settings)


def test_a_control_whose_natural_record_is_no_object_is_refused_naming_it(bundle, settings):
    record = json.loads(members(bundle)["study.json"])
    record["controls"][0] |= {"origin": "held-out", "natural": ["not", "an", "object"]}
    message = refused(rewritten(bundle, {"study.json": json.dumps(record).encode()}), settings)
    assert f"control signal {record['controls'][0]['name']!r}" in message and "natural" in message


def test_an_unknown_format_version_is_refused(bundle, settings):
    manifest = json.loads(members(bundle)["manifest.json"])
    manifest["version"] = 99
    message = refused(rewritten(bundle, {"manifest.json": json.dumps(manifest).encode()}, listed=False), settings)
    assert "manifest.json: format version 99 is not one this server reads (1)" in message


def test_a_record_of_unknown_fields_or_wrong_types_is_refused_naming_it(bundle, settings):
    record = json.loads(members(bundle)["study.json"])
    record["systems"][0]["owner_password"] = "x"
    assert "study.json: systems[0]: unknown field(s) 'owner_password'" in refused(
        rewritten(bundle, {"study.json": json.dumps(record).encode()}), settings)
    record = json.loads(members(bundle)["study.json"])
    record["study"]["scale_max"] = "many"
    assert "study.json: study: scale_max" in refused(rewritten(bundle, {"study.json": json.dumps(record).encode()}),
                                                     settings)


def test_a_record_naming_a_file_outside_its_folder_is_refused(bundle, settings, tmp_path):
    stimuli = json.loads(members(bundle)["stimuli.json"])
    stimuli[0]["token"] = "../../../outside"
    assert "stimuli.json[0]: its token '../../../outside' is no token" in refused(
        rewritten(bundle, {"stimuli.json": json.dumps(stimuli).encode()}), settings)
    record = json.loads(members(bundle)["study.json"])
    system = next(s for s in record["systems"] if s["checkpoint"])
    system["checkpoint_digest"], system["checkpoint"] = "../../outside", "../../outside.safetensors"
    assert "its digest '../../outside' is no digest" in refused(
        rewritten(bundle, {"study.json": json.dumps(record).encode()}), settings)
    assert not list(tmp_path.rglob("outside*"))


def test_something_that_is_no_zip_is_refused(bundle, settings, tmp_path):
    (tmp_path / "not.zip").write_bytes(b"PK\x03\x04 and then nothing")
    assert "not a zip file" in refused(tmp_path / "not.zip", settings)
