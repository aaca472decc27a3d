"""Estimates tables keep the whole record: the full covariance, the extras, ok and reason."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from deckpose.estimate.batch import estimate_batch
from deckpose.estimate.registry import EstimateOptions, parse_method
from deckpose.estimate.results_table import (
    COVARIANCE_COLUMNS,
    estimates_frame,
    estimates_from_frame,
)

from deckpose.camera import preset
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout
from deckpose.records import Detections


def _detections() -> list[Detections]:
    cam, lay = preset("8mp-square"), DeckLayout()
    rng = np.random.default_rng(3)
    out = []
    for f in range(5):
        pr = project_layout(lay, ShipPose(0.04, -0.02, 0.3, surge_m=0.2 * f), CameraPose.nadir(40.0), cam)
        pts = pr.points_px + rng.normal(0.0, 0.3, pr.points_px.shape)
        ids = np.arange(len(pts))
        if f == 4:  # too few beacons: a failed record with a reason
            pts, ids = pts[:2], ids[:2]
        out.append(Detections(pts, ids, frame_id=10 + f))
    return out


@pytest.mark.parametrize("label", ["thesis", "conic", "pnp", "pnp+mean"])
def test_a_table_gives_back_the_records_it_was_made_of(label, tmp_path):
    spec = parse_method(label)
    dets = _detections()
    ests = estimate_batch(spec.name, dets, preset("8mp-square"), DeckLayout(),
                          EstimateOptions(sigma_px=0.3, refine=spec.refine, posterior_mean=spec.posterior_mean))
    ids = [d.frame_id for d in dets]
    path = tmp_path / "est.parquet"
    assert [e.frame_id for e in ests] == ids  # each record says which frame it is of
    estimates_frame(ests).to_parquet(path)
    back = estimates_from_frame(pd.read_parquet(path))
    assert [b.frame_id for b in back] == ids
    assert any(e.ok for e in ests) and not ests[-1].ok
    for b, e in zip(back, ests, strict=True):
        assert (b.method, b.ok, b.reason) == (e.method, e.ok, e.reason)
        for attr in ("roll_rad", "pitch_rad", "yaw_rad", "surge_m", "sway_m", "height_m"):
            # degrees in the table: one rounding each way
            np.testing.assert_allclose(getattr(b, attr), getattr(e, attr), rtol=1e-15, atol=1e-300)
        if e.covariance is None:
            assert b.covariance is None
        else:
            np.testing.assert_array_equal(b.covariance, e.covariance)  # stored as is, radians and metres
        kept = {k: v for k, v in e.extras.items() if not math.isnan(v)}
        assert b.extras.keys() == kept.keys()
        for k, v in kept.items():  # angles in degrees in the table: one rounding each way
            assert b.extras[k] == v if not k.endswith("_rad") else b.extras[k] == pytest.approx(v, rel=1e-15), k


def test_the_covariance_columns_are_its_upper_triangle_in_si_units():
    names = [c for c, _, _ in COVARIANCE_COLUMNS]
    assert len(names) == 21 == len(set(names))
    assert names[0] == "cov_roll_rad__roll_rad" and "cov_roll_rad__height_m" in names
    assert "cov_height_m__roll_rad" not in names  # the lower triangle is the same numbers


def test_counts_ids_and_flags_are_typed_columns():
    dets = _detections()
    ests = estimate_batch("conic", dets, preset("8mp-square"), DeckLayout(), EstimateOptions(sigma_px=0.3))
    df = estimates_frame(ests)
    assert str(df["n_points"].dtype) == "Int64" and str(df["refined"].dtype) == "boolean"
    assert df["n_points"].iloc[0] == 13 and df["ok"].dtype == bool
