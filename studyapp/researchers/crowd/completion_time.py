"""How long participants take to complete a study, which a researcher sets the pay by
(crowd platforms pay and judge studies per hour): the median and the middle half of the
minutes from the entry link to the completion page, over those who completed it (not
those stopped by failed checks or screened out, who left early)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studyapp.models import Study


@dataclass(frozen=True)
class CompletionMinutes:
    n: int  # participants who completed
    median: float
    lower_quartile: float
    upper_quartile: float


def completion_minutes(study: Study) -> CompletionMinutes | None:
    """The minutes completed participants took; None before anyone has completed."""
    completed = study.participants.filter(finished_at__isnull=False, stopped_at__isnull=True,
                                          screened_out_at__isnull=True).values_list("started_at", "finished_at")
    minutes = np.array([(finished - started).total_seconds() / 60 for started, finished in completed])
    if not len(minutes):
        return None
    low, median, high = np.percentile(minutes, [25, 50, 75])
    return CompletionMinutes(len(minutes), float(median), float(low), float(high))


__all__ = ["CompletionMinutes", "completion_minutes"]
