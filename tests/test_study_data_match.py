"""A checkpoint that learnt from differently prepared data is refused when it is added (the
systems page and ``add_system``), naming each difference and the training options that
would match the study's checkpoints, and nothing of it is kept."""

from __future__ import annotations

import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from generation.motion.dataset_options import DatasetOptions
from studyapp.models import System
from tests.study_setup import train_tiny_moglow
from tests.test_study_researcher import files, new_study, researcher, site, stored_files, upload_checkpoint  # noqa: F401

OVERLAP = "overlap 0.75 in this checkpoint, 0.5 in the study's"


@pytest.fixture(scope="module")
def overlapping(files, tmp_path_factory):
    """A tiny MoGlow of the same clips in windows overlapping by three quarters (the study's by half)."""
    return train_tiny_moglow(files.clips, tmp_path_factory.mktemp("other") / "overlap.safetensors", 2,
                             files.root / "var" / "cache", DatasetOptions(overlap=0.75))


@pytest.mark.django_db
def test_a_checkpoint_of_differently_prepared_data_is_refused_on_the_systems_page(client, researcher, site, files,
                                                                                 overlapping, settings):
    study = new_study(researcher)
    assert upload_checkpoint(client, study, files.good.read_bytes()).status_code == 302
    kept = stored_files(settings.CHECKPOINT_ROOT)
    response = upload_checkpoint(client, study, overlapping.read_bytes(), filename="rnn.safetensors", name="RNN")
    page = response.content.decode()
    assert response.status_code == 400
    top = page.index('id="refused"')
    assert top < page.index("<h2>Upload a checkpoint</h2>")  # listed above the forms
    assert f"<li>rnn.safetensors: it learnt from data prepared otherwise than the study&#x27;s checkpoints (MoGlow): " \
           f"{OVERLAP.replace(chr(39), '&#x27;')}." in page
    assert ("Train it with: python -m generation train FOLDER ... --overlap 0.5 --scale 1 --up y "
            "(without --contents, --reverse or --mirror-pairs)</li>") in page
    assert list(study.systems.values_list("name", flat=True)) == ["MoGlow"]
    assert stored_files(settings.CHECKPOINT_ROOT) == kept  # nothing of it is kept


@pytest.mark.django_db
def test_add_system_refuses_it_too_with_exit_status_2(researcher, site, files, overlapping):
    study = new_study(researcher)
    call_command("add_system", str(study.pk), "MoGlow", str(files.good), stdout=open("/dev/null", "w"))
    with pytest.raises(CommandError, match=OVERLAP) as refused:
        call_command("add_system", str(study.pk), "RNN", str(overlapping))
    assert refused.value.returncode == 2
    assert not System.objects.filter(name="RNN").exists()
    call_command("add_system", str(study.pk), "Early", str(files.early), "--role", "bad",
                 stdout=open("/dev/null", "w"))  # the same data prepared the same way is welcome
