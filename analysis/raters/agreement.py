"""How far raters agree: Krippendorff's alpha of the ratings, per task x control class.

The clips (stimuli) are the units and the participants the coders: a crowd study's
reliability data are sparse (each participant rates a few clips, each clip is rated by a
few participants), which alpha handles as missing values, using every clip rated at
least twice. ``alpha = 1 - D_o / D_e``: the disagreement between ratings of the same
clip over the disagreement expected between any two ratings, so 1 is perfect agreement
and 0 agreement at chance; the ``interval`` metric squares differences of ratings (the
scale as numbers, as the mixed models read it), the ``ordinal`` one uses their ranks.

Computed by the ``krippendorff`` package (Castro 2017), whose results the tests check
against Krippendorff's (2011) worked example and a direct computation.
"""

from __future__ import annotations

from collections.abc import Sequence

import krippendorff
import numpy as np
import pandas as pd

from analysis.stats.anova import CELL, iter_cells

LEVELS = ("interval", "ordinal")


def reliability_matrix(frame: pd.DataFrame, dv: str = "value", participant: str = "participant",
                       stimulus: str = "stimulus") -> np.ndarray:
    """Participants x stimuli, the rating where given and NaN elsewhere (a repeated
    rating of one clip by one participant counts by its mean)."""
    wide = frame.pivot_table(index=participant, columns=stimulus, values=dv, aggfunc="mean")
    return wide.to_numpy(dtype=np.float64)


def rater_agreement(data: pd.DataFrame, dv: str = "value", participant: str = "participant",
                    stimulus: str = "stimulus", groupby: Sequence[str] = CELL) -> tuple[pd.DataFrame, list[str]]:
    """Per cell: stimuli (rated at least twice), participants, ratings (of those stimuli),
    alpha_interval and alpha_ordinal. Cells without a clip rated twice are left out and
    named in the notes."""
    rows, notes = [], []
    for key, frame in iter_cells(data, groupby):
        matrix = reliability_matrix(frame, dv, participant, stimulus)
        pairable = np.isfinite(matrix).sum(axis=0) >= 2
        where = " · ".join(map(str, key.values())) or "all ratings"
        if not pairable.any() or len(np.unique(matrix[:, pairable][np.isfinite(matrix[:, pairable])])) < 2:
            notes.append(f"No rater agreement for {where}: no clip was rated by two participants "
                         "with some spread in the ratings.")
            continue
        used = matrix[:, pairable]
        rows.append({**key, "stimuli": int(pairable.sum()),
                     "participants": int((np.isfinite(used).sum(axis=1) > 0).sum()),
                     "ratings": int(np.isfinite(used).sum()),
                     **{f"alpha_{level}": float(krippendorff.alpha(reliability_data=used,
                                                                   level_of_measurement=level))
                        for level in LEVELS}})
    return pd.DataFrame(rows), notes
