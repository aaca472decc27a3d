"""The resolution table's bound column: the mean over frames that have one, NaN (and no warning) where none has."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
from deckpose.evaluate.resolution_tables import resolution_table


def test_a_cell_without_any_bound_is_nan_without_a_warning() -> None:
    # two cells: 80 m where no frame was detected (every bound NaN), 20 m with bounds on some frames
    rows = []
    for h, crb in ((80.0, [np.nan, np.nan]), (20.0, [0.002, np.nan, 0.004])):
        for c in crb:
            rows.append({"detector": "cog", "method": "pnp", "camera": "64mp", "table_height_m": h,
                         "ok": not math.isnan(c), "roll_err_deg": 0.001, "pitch_err_deg": 0.001,
                         "yaw_err_deg": 0.001, "height_err_m": 0.01, "crb_roll_deg": c,
                         "crb_pitch_deg": c, "crb_yaw_deg": c, "crb_height_m": c})
    errors = pd.DataFrame(rows)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's "Mean of empty slice" reached users' terminals
        table = resolution_table(errors).set_index("table_height_m")
    assert math.isnan(table.loc[80.0, "crb_roll"])
    assert table.loc[20.0, "crb_height"] == (0.002 + 0.004) / 2
    assert table.loc[80.0, "failure_rate"] == 1.0
