from pathlib import Path

import numpy as np
import pytest
import yaml

from deckpose.errors import ConfigError
from deckpose.motion.config import parse_sea_run, sea_run_to_mapping
from deckpose.motion.irregular import ss6_frigate_sea
from deckpose.motion.ship import ffg7_ship

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "motion" / "ss6_frigate.yaml"


def test_defaults_are_the_ss6_frigate_scenario():
    run = parse_sea_run({})
    assert run.ship == ffg7_ship()
    assert run.sea == ss6_frigate_sea()
    assert (run.sea_state, run.duration_s, run.dt_s, run.seed) == (6, 600.0, 0.1, 0)


def test_committed_config_parses_and_round_trips():
    run = parse_sea_run(yaml.safe_load(CONFIG.read_text()))
    assert run.sea == ss6_frigate_sea() and run.seed == 1
    again = parse_sea_run(yaml.safe_load(yaml.safe_dump(sea_run_to_mapping(run))))
    assert again == run


def test_custom_ship_and_overrides():
    ship = {"length_m": 60.0, "beam_m": 9.0, "draught_m": 3.0, "block_coefficient": 0.45, "gm_m": 0.9,
            "roll_period_s": 8.0, "roll_damping_ratio": 0.08, "name": "patrol"}
    run = parse_sea_run({"ship": ship, "sea": {"sea_state": 4, "spectrum": "pm", "heading_deg": 90,
                                               "yaw": {"sigma_deg": 2.0}, "deck_offset_m": [-10, 0, 2]}})
    assert run.ship.name == "patrol" and run.ship.gm_m == 0.9
    assert run.sea.spectrum.hs_m == 1.88 and run.sea.spectrum.kind.value == "pm"
    assert np.degrees(run.sea.yaw.sigma) == pytest.approx(2.0) and run.sea.yaw.period_s == 30.0
    assert run.sea.deck_offset_m == (-10.0, 0.0, 2.0)


@pytest.mark.parametrize("mapping, match", [
    ({"sea": {"sea_state": 0}}, "1 to 9"),
    ({"sea": {"hs_m": -1.0}}, "> 0 m"),
    ({"sea": {"sea_state": 6, "hs_m": 8.0}}, "outside sea state 6"),
    ({"sea": {"spectrum": "foo"}}, "jonswap"),
    ({"sea": {"heading": 90}}, "unknown key"),
    ({"seeed": 3}, "unknown key"),
    ({"seed": -1}, "seed"),
    ({"dt_s": 0}, "dt_s"),
    ({"ship": {"length_m": 100.0}}, "missing key"),
    ({"ship": "titanic"}, "unknown ship preset"),
    ({"sea": {"speed_kn": "fast"}}, "speed_kn must be a number"),
    ({"sea": {"deck_offset_m": [1, 2]}}, "3 numbers"),
])
def test_bad_configs(mapping, match):
    with pytest.raises(ConfigError, match=match):
        parse_sea_run(mapping)
