"""``manage.py generate_stimuli STUDY_ID [--wait]``: plan and queue every stimulus, as the stimuli page does."""

import time

from django.core.management.base import BaseCommand

from studyapp.models import Stimulus
from studyapp.preregistration.fixed import StudyFixed
from studyapp.stimuli.clips import progress
from studyapp.stimuli.dispatch import BrokerUnavailable, generate_stimuli

from ._study import InputError, study_by_id


class Command(BaseCommand):
    help = "Create the study's stimuli (idempotently) and send the missing ones to the Celery workers."

    def add_arguments(self, parser):
        parser.add_argument("study_id", type=int)
        parser.add_argument("--seed", type=int, default=0)
        parser.add_argument("--wait", action="store_true", help="wait until the workers have finished every clip")
        parser.add_argument("--timeout", type=float, default=3600.0, help="seconds to wait at most (with --wait)")

    def handle(self, *args, **options):
        study = study_by_id(options["study_id"])
        if not 0 <= options["seed"] <= Stimulus.MAX_SEED:
            raise InputError(f"--seed {options['seed']}: a seed is a whole number from 0 to {Stimulus.MAX_SEED}")
        try:
            result = generate_stimuli(study, options["seed"])
        except (BrokerUnavailable, StudyFixed) as error:
            raise InputError(str(error)) from None
        self.stdout.write(f"{result.total} stimuli ({result.created} new), {result.queued} queued")
        if not options["wait"]:
            return
        deadline = time.monotonic() + options["timeout"]
        last = None
        while True:
            state = progress(study)
            counts = state["counts"]
            line = f"{counts['done']}/{state['total']} done, {counts['running']} running, {counts['failed']} failed"
            if line != last:
                self.stdout.write(line)
                last = line
            if counts["queued"] + counts["running"] == 0:
                break
            if time.monotonic() > deadline:
                raise InputError(f"gave up waiting after {options['timeout']:g} s: {line} (is a worker running?)")
            time.sleep(0.5)
        if state["failed"]:
            reasons = "\n".join(f"  {f['system']} / {f['control']}: {f['error']}" for f in state["failed"])
            raise InputError(f"{len(state['failed'])} stimuli failed:\n{reasons}")
