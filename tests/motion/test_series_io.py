import math

import numpy as np
import pandas as pd
import pytest

from deckpose.errors import InputDataError
from deckpose.motion.irregular import irregular_series, ss6_frigate_sea
from deckpose.motion.series import MotionSeries, read_series, write_series
from deckpose.motion.ship import ffg7_ship


@pytest.fixture(scope="module")
def series() -> MotionSeries:
    return irregular_series(ffg7_ship(), ss6_frigate_sea(), duration_s=30.0, dt_s=0.1,
                            rng=np.random.default_rng(0))


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
@pytest.mark.parametrize("angles", ["deg", "rad"])
def test_round_trip(tmp_path, series, ext, angles):
    path = tmp_path / f"m{ext}"
    write_series(series, path, angles=angles)
    df = pd.read_csv(path) if ext == ".csv" else pd.read_parquet(path)
    assert list(df.columns) == ["t_s", f"roll_{angles}", f"pitch_{angles}", f"yaw_{angles}",
                                "heave_m", "surge_m", "sway_m"]
    back = read_series(path, angles=angles)
    for name in ("t_s", "roll_rad", "pitch_rad", "yaw_rad", "heave_m", "surge_m", "sway_m"):
        np.testing.assert_allclose(getattr(back, name), getattr(series, name), rtol=1e-15, atol=1e-15)


def test_recorded_file_without_surge_sway(tmp_path):
    path = tmp_path / "ship.csv"
    pd.DataFrame({"t_s": [0.0, 0.2, 0.4], "roll_deg": [1.0, 2.0, 3.0], "pitch_deg": [0.5, 0.0, -0.5],
                  "yaw_deg": [10.0, 10.0, 10.0], "heave_m": [0.1, 0.2, 0.1]}).to_csv(path, index=False)
    s = read_series(path)
    assert s.roll_rad[2] == pytest.approx(math.radians(3.0))
    assert not np.any(s.surge_m) and not np.any(s.sway_m)
    assert s.pose(1).yaw_rad == pytest.approx(math.radians(10.0))


def test_missing_columns(tmp_path):
    path = tmp_path / "bad.csv"
    pd.DataFrame({"t_s": [0.0, 1.0], "roll_deg": [0.0, 1.0]}).to_csv(path, index=False)
    with pytest.raises(InputDataError, match=r"missing column\(s\).*pitch_deg"):
        read_series(path)


def test_radians_hint(tmp_path, series):
    path = tmp_path / "rad.csv"
    write_series(series, path, angles="rad")
    with pytest.raises(InputDataError, match="radians"):
        read_series(path)


@pytest.mark.parametrize("t", [[0.0, 0.2, 0.1], [0.0, 0.1, 0.1]])
def test_non_monotonic_time(tmp_path, t):
    path = tmp_path / "t.csv"
    pd.DataFrame({"t_s": t, "roll_deg": 0.0, "pitch_deg": 0.0, "yaw_deg": 0.0, "heave_m": 0.0}).to_csv(
        path, index=False)
    with pytest.raises(InputDataError, match="strictly increasing"):
        read_series(path)


def test_bad_extension_and_missing_file(tmp_path):
    with pytest.raises(InputDataError, match=".csv or .parquet"):
        read_series(tmp_path / "m.txt")
    with pytest.raises(InputDataError, match="does not exist"):
        read_series(tmp_path / "none.csv")
