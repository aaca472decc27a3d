"""Parquet tables say what they hold, which deckpose wrote them, and each column's unit."""

from __future__ import annotations

import pandas as pd
import pyarrow.parquet as pq

from deckpose import __version__
from deckpose.tables import TABLE_FORMAT, column_units, read_table, table_metadata, write_table


def test_a_parquet_table_carries_its_kind_version_and_units(tmp_path):
    df = pd.DataFrame({"frame_id": [0, 1], "roll_deg": [0.1, 0.2], "height_m": [40.0, 41.0],
                       "u_px": [1.5, 2.5], "stamp_ns": [0, 10], "spot_flux_e": [3e3, 4e3],
                       "sea_drift_m_per_s": [0.1, 0.2], "ok": [True, False]})
    path = tmp_path / "t.parquet"
    write_table(df, path, "motion series")
    meta = table_metadata(path)
    assert meta["format"] == TABLE_FORMAT and meta["kind"] == "motion series"
    assert meta["deckpose_version"] == __version__
    assert meta["units"] == {"roll_deg": "deg", "height_m": "m", "u_px": "px", "stamp_ns": "ns",
                             "spot_flux_e": "e-", "sea_drift_m_per_s": "m/s"}
    pd.testing.assert_frame_equal(read_table(path), df)  # the pandas metadata is kept too
    assert b"pandas" in pq.read_schema(path).metadata


def test_units_come_from_the_longest_matching_suffix():
    assert column_units(["gain_dn_per_e", "x_m", "sigma_px2", "n_points"]) == {
        "gain_dn_per_e": "DN/e-", "x_m": "m", "sigma_px2": "px^2"}


def test_a_rendered_dataset_and_its_detections_carry_the_metadata(tmp_path):
    from deckpose.detect.run import detect_run
    from deckpose.render.config import default_config
    from deckpose.render.dataset import render_dataset

    from deckpose.run_folder import RunPaths

    cfg = default_config()
    out = tmp_path / "ds"
    import dataclasses

    cfg = dataclasses.replace(cfg, heights_m=cfg.heights_m[:1], cameras=cfg.cameras[:1])
    render_dataset(cfg, out, workers=0, resume=False, progress=False)
    run = RunPaths(out)
    assert table_metadata(run.frames)["kind"] == "frames"
    assert table_metadata(run.beacons)["units"]["u_px"] == "px"
    detect_run(out, "cog")
    assert table_metadata(run.detections("cog"))["kind"] == "detections"
