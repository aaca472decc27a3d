"""One estimates schema for every method: a run's estimates read together by glob.

A small run is estimated with every method and variant (one frame with too few
beacons, so every method fails it; one with a beacon moved, an outlier), then read by
glob with polars and DuckDB: every row is there, every column has its documented type,
counts are integers, flags booleans, and a failed row is null where it has no value.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from deckpose.detect.tables import read_detections as read_detections_file
from deckpose.estimate.results_table import COLUMN_NAMES, estimates_frame, estimates_from_frame
from scipy.spatial.transform import Rotation

from deckpose.cli import main
from deckpose.errors import InputDataError
from deckpose.estimates_schema import ESTIMATE_COLUMNS, EXTRAS_JSON, SIGMA_COLUMNS
from deckpose.records import PoseEstimate
from deckpose.run_folder import R_world_from_cam_all, RunPaths, read_detections, read_frames
from deckpose.table_schemas import Column
from deckpose.tables import SCHEMAS, arrow_schema, column_units, table_metadata, write_table
from tests.evaluate.fake_run import make_fake_run

LABELS = ("thesis", "thesis+refine", "thesis+mean", "conic", "conic+refine", "conic+mean",
          "pnp", "pnp+refine", "pnp+mean")
FAILED_FRAME, OUTLIER_FRAME, OUTLIER_BEACON = 0, 1, 4
POSE = ("roll_deg", "pitch_deg", "yaw_deg", "surge_m", "sway_m", "height_m")
POLARS_TYPES = {"int64": "Int64", "float64": "Float64", "bool": "Boolean", "string": "String"}
DUCKDB_TYPES = {"int64": "BIGINT", "float64": "DOUBLE", "bool": "BOOLEAN", "string": "VARCHAR"}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A fake run (6 frames) estimated with every method and variant."""
    root = make_fake_run(tmp_path_factory.mktemp("schemas") / "run", heights=(20.0,), n_per_cell=3)
    path = root / "detections" / "fake.parquet"
    det = pd.read_parquet(path)
    det = det[(det.frame_id != FAILED_FRAME) | (det.beacon_id < 2)]  # too few beacons for any method
    moved = (det.frame_id == OUTLIER_FRAME) & (det.beacon_id == OUTLIER_BEACON)
    det.loc[moved, "u_px"] += 40.0  # 130 sigma: an outlier that conic and pnp remove
    det.to_parquet(path, index=False)
    for label in LABELS:
        assert main(["estimate", "--run", str(root), "--detector", "fake", "--method", label,
                     "--no-progress"]) == 0, label
    return root


def _glob(root) -> str:
    return str(root / "estimates" / "*.parquet")


def test_every_table_has_exactly_the_documented_columns_and_types(run):
    files = sorted((run / "estimates").glob("*.parquet"))
    assert len(files) == len(LABELS)
    want = arrow_schema(ESTIMATE_COLUMNS)
    for f in files:
        schema = pq.read_schema(f)
        assert schema.names == list(COLUMN_NAMES), f.name
        assert [fld.type for fld in schema] == [fld.type for fld in want], f.name
        meta = table_metadata(f)
        assert meta["kind"] == "estimates"
        assert meta["descriptions"] == {c.name: c.description for c in ESTIMATE_COLUMNS}
        assert meta["units"] == {c.name: c.unit for c in ESTIMATE_COLUMNS if c.unit}
        assert meta["units"]["cov_roll_rad__height_m"] == "rad m"  # not the "m" of its suffix


def test_polars_reads_a_runs_estimates_by_glob(run):
    pl = pytest.importorskip("polars")
    df = pl.read_parquet(_glob(run))
    frames = pd.read_parquet(run / "frames.parquet")
    assert df.height == len(LABELS) * len(frames)
    assert sorted(df["method"].unique().to_list()) == sorted(LABELS)
    assert df.columns == list(COLUMN_NAMES)
    for c in ESTIMATE_COLUMNS:
        assert str(df.schema[c.name]) == POLARS_TYPES[c.dtype], c.name
    assert df.filter(pl.col("frame_id") == FAILED_FRAME)["ok"].to_list() == [False] * len(LABELS)
    assert df[EXTRAS_JSON].null_count() == df.height  # every built-in extra has its own column


def test_duckdb_reads_a_runs_estimates_by_glob(run):
    duckdb = pytest.importorskip("duckdb")
    con = duckdb.connect()
    rel = con.sql(f"SELECT * FROM read_parquet('{_glob(run)}')")
    assert rel.columns == list(COLUMN_NAMES)
    types = dict(zip(rel.columns, (str(t) for t in rel.types)))
    assert types == {c.name: DUCKDB_TYPES[c.dtype] for c in ESTIMATE_COLUMNS}
    n_frames = len(pd.read_parquet(run / "frames.parquet"))
    counts = dict(con.sql(f"SELECT method, count(*) FROM read_parquet('{_glob(run)}') GROUP BY method").fetchall())
    assert counts == dict.fromkeys(LABELS, n_frames)
    removed = con.sql(f"SELECT method, n_outliers_removed, outlier_id_0 FROM read_parquet('{_glob(run)}') "
                      f"WHERE frame_id = {OUTLIER_FRAME} AND method NOT LIKE 'thesis%'").fetchall()
    assert len(removed) == 6 and all(r[1:] == (1, OUTLIER_BEACON) for r in removed), removed


def test_counts_ids_and_flags_are_integers_and_booleans_in_pandas(run):
    for f in (run / "estimates").glob("*.parquet"):
        df = pd.read_parquet(f)
        for c in ESTIMATE_COLUMNS:
            if c.dtype == "int64":
                assert str(df[c.name].dtype) == ("Int64" if c.nullable else "int64"), (f.name, c.name)
            elif c.dtype == "bool":
                assert str(df[c.name].dtype) == ("boolean" if c.nullable else "bool"), (f.name, c.name)
            elif c.dtype == "float64":
                assert df[c.name].dtype == np.float64, (f.name, c.name)


def test_a_failed_row_is_null_where_it_has_no_value(run):
    for f in (run / "estimates").glob("*.parquet"):
        row = pd.read_parquet(f).set_index("frame_id").loc[FAILED_FRAME]
        assert not row["ok"] and row["reason"], f.name
        cov = [c.name for c in ESTIMATE_COLUMNS if c.name.startswith("cov_")]
        assert row[[*POSE, *SIGMA_COLUMNS, *cov]].isna().all(), f.name
        assert row[["dof", "n_solutions", "posterior_mean", "thesis_minor_axis_z"]].isna().all(), f.name


def test_the_tables_give_back_their_records(run):
    for f in (run / "estimates").glob("*.parquet"):
        back = estimates_from_frame(pd.read_parquet(f))
        assert [b.frame_id for b in back] == sorted(b.frame_id for b in back)
        assert not back[FAILED_FRAME].ok
        ok = [b for b in back if b.ok]
        assert ok and all(math.isfinite(b.roll_rad) for b in ok), f.name
        if "+mean" in f.name:
            assert all("ml_roll_rad" in b.extras and "posterior_sigma_yaw_rad" in b.extras for b in ok)


def test_a_plugins_extras_are_kept_as_json():
    """Extras no column holds go into ``extras_json``; a known one still fills its column."""
    est = PoseEstimate("plugin", True, roll_rad=0.1, pitch_rad=0.0, yaw_rad=0.0, height_m=30.0,
                       extras={"n_points": 7.0, "alt_roll_rad": 0.2, "my_score": 2.5, "my_ratio": math.inf})
    df = estimates_frame([est])
    assert list(df.columns) == list(COLUMN_NAMES)
    assert json.loads(df.loc[0, EXTRAS_JSON]) == {"my_ratio": None, "my_score": 2.5}
    assert df.loc[0, "n_points"] == 7 and df.loc[0, "alt_roll_deg"] == pytest.approx(math.degrees(0.2))
    back = estimates_from_frame(df)[0]
    assert back.extras["my_score"] == 2.5 and math.isnan(back.extras["my_ratio"])
    assert back.extras["alt_roll_rad"] == pytest.approx(0.2, rel=1e-15) and back.extras["n_points"] == 7.0


def test_plugin_json_is_queryable_in_duckdb(tmp_path):
    duckdb = pytest.importorskip("duckdb")
    ests = [PoseEstimate("plugin", True, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0, height_m=30.0,
                         extras={"my_score": s}, frame_id=i) for i, s in enumerate((1.5, 2.5))]
    path = tmp_path / "plugin.parquet"
    write_table(estimates_frame(ests), path, "estimates")
    got = duckdb.sql(f"SELECT CAST(json_extract(extras_json, '$.my_score') AS DOUBLE) FROM "
                     f"read_parquet('{path}') ORDER BY frame_id").fetchall()
    assert got == [(1.5,), (2.5,)]


def test_no_estimate_at_all_is_still_the_whole_schema(tmp_path):
    path = tmp_path / "none.parquet"
    write_table(estimates_frame([]), path, "estimates")
    assert pq.read_schema(path).names == list(COLUMN_NAMES)
    assert [f.type for f in pq.read_schema(path)] == [f.type for f in arrow_schema(ESTIMATE_COLUMNS)]


def test_an_estimates_table_off_its_schema_is_refused(tmp_path):
    df = estimates_frame([PoseEstimate.failed("x", "no beacons")])
    with pytest.raises(InputDataError, match="missing \\['n_points'\\]"):
        write_table(df.drop(columns=["n_points"]), tmp_path / "e.parquet", "estimates")
    with pytest.raises(InputDataError, match="unexpected \\['mine'\\]"):
        write_table(df.assign(mine=1.0), tmp_path / "e.csv", "estimates")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("kind", sorted(SCHEMAS))
def test_every_column_is_documented_with_a_unit_that_agrees_with_its_name(kind):
    cols: tuple[Column, ...] = SCHEMAS[kind]
    assert len({c.name for c in cols}) == len(cols)
    for c in cols:
        assert c.description and c.dtype in ("int64", "float64", "bool", "string"), c.name
        suffix_unit = column_units([c.name]).get(c.name)
        if suffix_unit and not c.name.startswith("cov_"):  # cov_<a>__<b>: the product of a's and b's
            assert c.unit == suffix_unit, c.name
        if c.dtype in ("bool", "string"):
            assert not c.unit, c.name


def test_other_tables_carry_their_columns_descriptions_and_units(tmp_path):
    df = pd.DataFrame({"frame_id": [0], "beacon_id": [3], "flux_dn": [120.0], "snr": [40.0],
                       "cov_uu": [0.1], "mine_m": [1.0]})
    path = tmp_path / "d.parquet"
    write_table(df, path, "detections")  # not held to its schema: descriptions for what it knows
    meta = table_metadata(path)
    assert meta["units"] == {"flux_dn": "DN", "cov_uu": "px^2", "mine_m": "m"}
    assert set(meta["descriptions"]) == {"frame_id", "beacon_id", "flux_dn", "snr", "cov_uu"}
    assert "signal-to-noise" in meta["descriptions"]["snr"]


def test_tables_of_an_older_deckpose_read_with_todays_names_and_units(tmp_path):
    # deckpose-table/2 named the truth attitude roll_rad (radians), the camera rotation r00..r22
    # and the detections' flux and score; they read as roll_deg (degrees), R_world_from_cam_ij,
    # flux_dn and snr. Written out here as an older deckpose wrote them.
    root = tmp_path / "old"
    (root / "detections").mkdir(parents=True)
    R = Rotation.from_euler("ZYX", [0.3, -0.2, 0.1]).as_matrix()
    old = {"frame_id": [0], "roll_rad": [0.1], "pitch_rad": [-0.2], "yaw_rad": [math.pi]}
    old.update({f"r{i}{j}": [R[i, j]] for i in range(3) for j in range(3)})
    pd.DataFrame(old).to_parquet(root / "frames.parquet")
    (root / "beacons.parquet").write_bytes((root / "frames.parquet").read_bytes())
    (root / "manifest.json").write_text("{}")
    pd.DataFrame({"frame_id": [0], "beacon_id": [2], "u_px": [1.0], "v_px": [2.0], "cov_uu": [1.0], "cov_uv": [0.0],
                  "cov_vv": [1.0], "flux": [7.0], "size_px": [1.5], "score": [12.5], "detector": ["cog"]}
                 ).to_parquet(root / "detections" / "cog.parquet")
    run = RunPaths(root)
    frames = read_frames(run)
    assert "roll_rad" not in frames and "r00" not in frames
    assert frames.loc[0, ["roll_deg", "pitch_deg", "yaw_deg"]].tolist() == pytest.approx(
        [math.degrees(0.1), math.degrees(-0.2), 180.0], rel=1e-15)
    np.testing.assert_array_equal(R_world_from_cam_all(frames)[0], R)
    dets = read_detections(run, "cog")
    assert dets.loc[0, "flux_dn"] == 7.0 and dets.loc[0, "snr"] == 12.5 and "score" not in dets
    assert read_detections_file(run.detections("cog"))[0].score.tolist() == [12.5]
