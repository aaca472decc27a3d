"""Bad input gets a clear ConfigError before any frame is rendered."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from deckpose.render.config import config_from_dict, config_to_dict, load_config
from deckpose.render.plan import plan_frames, thesis_series

from deckpose.errors import ConfigError
from deckpose.rotation import R_from_thesis, R_from_zyx

from .conftest import tiny_doc

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"colour": "red"}, r"unknown key\(s\) \['colour'\]"),
        ({"sensor": {"bitdepth": 8}}, r"sensor: unknown key"),
        ({"heights_m": [30, -5]}, r"heights_m\[1\]: must be > 0, got -5"),
        ({"heights_m": []}, r"non-empty list"),
        ({"layout": {"n_ring": 0}}, r"n_ring is 0"),
        ({"layout": {"n_ring": 2}}, r"at least 3 ring beacons"),
        ({"lighting": ["midnight"]}, r"'midnight' is not one of"),
        ({"backend": "glx"}, r"'glx' is not one of"),
        ({"sensor": {"bit_depth": 10}}, r"8, 12 or 16"),
        ({"cameras": [{"preset": "3mp"}]}, r"unknown camera preset"),
        ({"motion": {"source": "file"}}, r"needs motion.path"),
        ({"motion": {"source": "fixed", "attitudes_deg": [[1, 2]]}}, r"attitudes_deg"),
        ({"scene": {"deck_half_size_m": 5.0}}, r"must exceed the ring radius"),
        ({"scene": {"antialias_samples": 3}}, r"scene.antialias_samples: one of 0, 2, 4, 8 \(0: off\), got 3"),
    ],
)
def test_bad_config_is_rejected_with_a_clear_message(over: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        config_from_dict(tiny_doc(**over))


def test_camera_inside_or_below_the_deck_is_rejected() -> None:
    # heave 3 m lifts the deck to the camera at 2.5 m
    cfg = config_from_dict(tiny_doc(heights_m=[2.5], motion={"source": "fixed", "attitudes_deg": [[0, 0, 0, 3.0, 0, 0]]}))
    with pytest.raises(ConfigError, match="below the deck"):
        plan_frames(cfg)


def test_unreadable_motion_file_fails_before_rendering(tmp_path: Path) -> None:
    bad = tmp_path / "motion.csv"
    bad.write_text("t_s,roll\n0,1\n")
    for path in (bad, tmp_path / "missing.csv"):
        cfg = config_from_dict(tiny_doc(motion={"source": "file", "path": str(path)}))
        with pytest.raises(ConfigError, match="motion.path"):
            plan_frames(cfg)


def test_sea_state_source_uses_the_irregular_sea_generator() -> None:
    from deckpose.render.plan import load_motion

    params = {"ship": "ffg7", "sea": {"sea_state": 6, "heading_deg": 135, "speed_kn": 15},
              "duration_s": 20, "dt_s": 0.5, "seed": 3}
    cfg = config_from_dict(tiny_doc(motion={"source": "sea_state", "params": params}))
    a = load_motion(cfg.motion)
    b = load_motion(cfg.motion)
    assert len(a) == 41 and np.array_equal(a.roll_rad, b.roll_rad)  # seeded: same series
    assert np.std(a.roll_rad) > 0
    bad = config_from_dict(tiny_doc(motion={"source": "sea_state", "params": {"sea": {"sea_state": 12}}}))
    with pytest.raises(ConfigError, match="sea state"):
        load_motion(bad.motion)


def test_unreadable_config_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "nope.yaml")
    (tmp_path / "bad.yaml").write_text("cameras: [\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(tmp_path / "bad.yaml")


def test_resolved_config_round_trips() -> None:
    cfg = config_from_dict(tiny_doc())
    assert config_from_dict(config_to_dict(cfg)) == cfg


#: The one shipped config that is not a render config: the analytic-spot dataset's.
SYNTHETIC_CONFIG = "detect_bench_synthetic.yaml"


@pytest.mark.parametrize(
    "name", sorted(p.name for p in (REPO / "configs").glob("*.yaml") if p.name != SYNTHETIC_CONFIG)
)
def test_shipped_configs_parse(name: str) -> None:
    cfg = load_config(REPO / "configs" / name)
    assert cfg.cameras and cfg.heights_m


#: The realistic configs (issue 23): the detector ladder's rungs and conditions, the ship look.
REALISTIC_CONFIGS = sorted([*(p.name for p in (REPO / "configs").glob("detector_benchmark_*.yaml")),
                            "realistic_ship.yaml", "ship_day.yaml"])


@pytest.mark.parametrize("name", REALISTIC_CONFIGS)
def test_realistic_configs_take_square_pixels(name: str) -> None:
    """The thesis cameras' non-square pixels are for the thesis experiment; a real sensor's are square."""
    cfg = load_config(REPO / "configs" / name)
    for cam in cfg.cameras_by_name().values():
        assert cam.fx == pytest.approx(cam.fy, rel=1e-12), (name, cam)


def test_shipped_synthetic_dataset_config_parses() -> None:
    from deckpose.detect.synthetic_dataset import read_config

    cfg = read_config(REPO / "configs" / SYNTHETIC_CONFIG)
    assert cfg.cameras and cfg.heights_m


def test_noise_free_crb_config_differs_from_its_noisy_twin_only_in_noise() -> None:
    import dataclasses

    noisy = load_config(REPO / "configs" / "detector_crb.yaml")
    clean = load_config(REPO / "configs" / "detector_crb_noisefree.yaml")
    assert noisy.sensor.noise and not clean.sensor.noise
    assert dataclasses.replace(clean, name=noisy.name, sensor=noisy.sensor) == noisy


def test_embedded_default_is_the_smoke_config() -> None:
    from deckpose.render.config import default_config

    assert default_config() == load_config(REPO / "configs" / "smoke.yaml")
    assert len(plan_frames(default_config())) == 24


def test_embedded_demo_approach_is_the_small_approach_config() -> None:
    from deckpose.render.config import approach_demo_config

    assert approach_demo_config() == load_config(REPO / "configs" / "approach_small.yaml")
    assert len(plan_frames(approach_demo_config())) == 61   # 30 s at 2 Hz, both ends


def test_thesis_sweep_size() -> None:
    cfg = load_config(REPO / "configs" / "thesis_sweep.yaml")
    frames = plan_frames(cfg)
    assert len(frames) == 4 * 5 * 495
    assert {f.camera_name for f in frames} == {"4mp-2312x1734", "8mp-3840x2160", "16mp-4624x3468",
                                                "64mp-9248x6936"}


def test_thesis_series_converts_angles_and_heave() -> None:
    import pandas as pd

    series = thesis_series()
    import deckpose

    raw = pd.read_csv(Path(deckpose.__file__).parent / "data" / "thesis_motion_series.csv")
    i = 123
    R_t = R_from_thesis(*np.radians(raw.loc[i, ["roll_deg", "pitch_deg", "yaw_deg"]].to_numpy(float)))
    R_z = R_from_zyx(series.roll_rad[i], series.pitch_rad[i], series.yaw_rad[i])
    np.testing.assert_allclose(R_z, R_t, atol=1e-12)
    # thesis: camera distance = table height + heave; ours: distance = height - heave_m
    assert series.heave_m[i] == pytest.approx(-raw.loc[i, "heave_m"])


def test_frame_ids_and_seeds_are_a_function_of_the_config() -> None:
    a = plan_frames(config_from_dict(tiny_doc()))
    b = plan_frames(config_from_dict(tiny_doc()))
    assert [f.frame_id for f in a] == list(range(len(a))) == [f.frame_id for f in b]
    assert [f.seed for f in a] == [f.seed for f in b]
    assert len({f.seed for f in a}) == len(a)


def test_an_empty_config_says_it_is_empty(tmp_path: Path) -> None:
    # it said "expected a YAML mapping at the top level", which does not tell an empty file
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(ConfigError, match="the config is empty"):
        load_config(empty)
    assert (REPO / "configs" / "smoke.yaml").is_file()  # the config the message names
