"""Auto-exposure across frames (``sensor.auto_exposure.time_constant_s`` / ``max_step_stops``).

The controller is checked against the closed forms of a first-order system and of a
rate limiter written out here; the metering pre-pass against the per-frame auto-exposure
it must reproduce at full scale; the dataset against a recurrence written out here.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from deckpose.render.config import config_from_dict, config_to_dict
from deckpose.render.dataset import render_dataset
from deckpose.render.exposure_control import controlled_exposures, time_sequences
from deckpose.render.plan import plan_frames
from deckpose.render.sensor_config import AutoExposureSpec

from deckpose.errors import ConfigError

from .conftest import tiny_doc

# float64 recurrences and exp/log of values of order 1: a few ulps a step over tens of steps
RTOL = 1e-12


def test_a_step_of_the_scene_gives_the_first_order_response() -> None:
    """Meterings A then B from frame j: e_k = A up to j, then log e_k = log B + (log A - log B) exp(-(t_k - t_j)/tau)."""
    tau, dt, j = 0.35, 0.1, 5
    a_exp, b_exp = 0.4, 3.0
    t = dt * np.arange(30)
    metered = np.where(np.arange(30) < j, a_exp, b_exp)
    ae = AutoExposureSpec(time_constant_s=tau, min_exposure=0.01, max_exposure=100.0)
    got = controlled_exposures(metered, t, ae)
    want = np.where(t < t[j], a_exp,
                    np.exp(np.log(b_exp) + (np.log(a_exp) - np.log(b_exp)) * np.exp(-(t - t[j]) / tau)))
    np.testing.assert_allclose(got, want, rtol=RTOL)
    # after 10 time constants the exposure is within exp(-10) of B in log: the steady state
    assert abs(math.log(got[-1] / b_exp)) < math.exp(-(t[-1] - t[j]) / tau) * math.log(b_exp / a_exp) * 1.0001


def test_a_constant_scene_keeps_the_per_frame_exposure() -> None:
    """Steady state: with every metering equal, the controller's exposure is that metering (per-frame AE)."""
    ae = AutoExposureSpec(time_constant_s=0.5, max_step_stops=0.5)
    got = controlled_exposures(np.full(12, 2.75), 0.05 * np.arange(12), ae)
    np.testing.assert_allclose(got, 2.75, rtol=RTOL)


def test_the_step_limit_ramps_by_at_most_its_stops_per_frame() -> None:
    """tau = 0 with a limit of s stops: a 5-stop drop is covered s stops a frame, one frame late."""
    s, j = 1.5, 3
    metered = np.where(np.arange(10) < j, 8.0, 8.0 / 2 ** 5)
    got = controlled_exposures(metered, 0.1 * np.arange(10), AutoExposureSpec(max_step_stops=s, min_exposure=0.01))
    n = np.clip(np.arange(10) - j, 0, None)  # frames since the change
    np.testing.assert_allclose(got, 8.0 / 2 ** np.minimum(n * s, 5.0), rtol=RTOL)


def test_uneven_frame_times_use_each_gap() -> None:
    """Each step's gain is 1 - exp(-dt_k / tau) for its own gap (a dropped frame decays further)."""
    tau = 0.2
    t = np.array([0.0, 0.1, 0.2, 0.5, 0.55])
    metered = np.array([1.0, 4.0, 4.0, 4.0, 4.0])
    got = controlled_exposures(metered, t, AutoExposureSpec(time_constant_s=tau))
    # after the change at t = 0.1 (seen from the frame at 0.2 on), log e relaxes to log 4 with tau
    want = [1.0, 1.0, *np.exp(np.log(4.0) * (1 - np.exp(-(t[2:] - t[1]) / tau)))]
    np.testing.assert_allclose(got, want, rtol=RTOL)


def test_exposures_stay_within_the_limits() -> None:
    ae = AutoExposureSpec(time_constant_s=0.1, min_exposure=0.5, max_exposure=2.0)
    got = controlled_exposures([1.0, 1.0, 2.0, 2.0, 2.0, 2.0, 2.0], 0.1 * np.arange(7), ae)
    assert got.min() >= 0.5 and got.max() <= 2.0


def test_time_sequences_are_per_camera_height_and_lighting_in_time_order() -> None:
    cfg = config_from_dict(tiny_doc(motion={"source": "fixed", "attitudes_deg": [[0, 0, 0], [1, 0, 0], [2, 0, 0]]}))
    plan = plan_frames(cfg)
    seqs = time_sequences(plan)
    assert len(seqs) == 2 * 2  # heights x lighting, one camera
    assert sorted(i for s in seqs for i in s) == list(range(len(plan)))
    for s in seqs:
        assert len({(plan[i].camera_name, plan[i].height_m, plan[i].lighting) for i in s}) == 1
        assert [plan[i].t_s for i in s] == sorted(plan[i].t_s for i in s)


# the deck leaves the view (40 m surge) after frame 2: a sudden change of the metered scene
_STEP_MOTION = {"source": "fixed", "dt_s": 0.1, "attitudes_deg": [[0, 0, 0]] * 3 + [[0, 0, 0, 0, 40, 0]] * 3}


def _step_doc(**ae: object) -> dict[str, object]:
    return tiny_doc(heights_m=[25.0], lighting=["day"], motion=_STEP_MOTION,
                    sensor={"bit_depth": 8, "read_noise_e": 5, "auto_exposure": {"target": 0.18, **ae}})


def test_dataset_exposures_follow_the_controller_and_resume(tmp_path: Path, egl_renderer_factory) -> None:
    per_frame = config_from_dict(_step_doc())
    egl_renderer_factory(per_frame)  # this process's GL platform
    ref = pd.read_parquet(render_dataset(per_frame, tmp_path / "per_frame", workers=0, progress=False)
                          / "frames.parquet")
    tau = 0.15
    cfg = config_from_dict(_step_doc(time_constant_s=tau, metering_scale=1.0))
    out = render_dataset(cfg, tmp_path / "controlled", workers=0, progress=False)
    frames = pd.read_parquet(out / "frames.parquet")
    # at full scale the pre-pass meters what each frame meters of itself (same raster, same
    # histogram metering): equal to the per-frame run's exposures but for float rounding
    np.testing.assert_allclose(frames["metered_exposure"], ref["exposure"], rtol=1e-9)
    m, t = frames["metered_exposure"].to_numpy(), frames["t_s"].to_numpy()
    want = [m[0]]
    for k in range(1, len(m)):  # the controller written out
        want.append(math.exp(math.log(want[-1]) + (1 - math.exp(-(t[k] - t[k - 1]) / tau))
                             * (math.log(m[k - 1]) - math.log(want[-1]))))
    np.testing.assert_allclose(frames["exposure"], want, rtol=RTOL)
    assert abs(math.log(m[3] / m[2])) > 0.2  # the scene did change (the test is not vacuous)
    # the frame of the change is exposed for the scene before it (the controller lags a frame)
    assert abs(math.log(frames["exposure"][3] / m[2])) < 0.01 * abs(math.log(m[3] / m[2]))
    block = json.loads((out / "manifest.json").read_text())["sensor"]["exposure"]
    assert (block["time_constant_s"], block["metering_scale"]) == (tau, 1.0)
    # resume: a lost frame is rendered again at the same controlled exposure, bit for bit
    image = out / frames["image"][4]
    before = image.read_bytes()
    image.unlink()
    (out / ".parts" / "000004.json").unlink()
    render_dataset(cfg, out, workers=0, progress=False, resume=True)
    assert image.read_bytes() == before
    pd.testing.assert_frame_equal(pd.read_parquet(out / "frames.parquet"), frames)


def test_low_resolution_metering_is_close_to_the_full_frame(egl_renderer_factory) -> None:
    """Metering at a quarter of the size sees the same scene: within 5 % of the full-frame metering
    (the histogram of a 4x smaller raster of the same view; textures and edges average differently)."""
    from deckpose.render.exposure_control import metering_exposure

    cfg = config_from_dict(_step_doc())
    renderer = egl_renderer_factory(cfg)
    cam = next(iter(cfg.cameras_by_name().values()))
    ae = cfg.sensor.auto_exposure
    assert ae is not None
    for spec in plan_frames(cfg)[::3]:
        full = metering_exposure(spec, cam, renderer, cfg.sensor, cfg.scene.shading,
                                 AutoExposureSpec(target=ae.target, metering_scale=1.0))
        low = metering_exposure(spec, cam, renderer, cfg.sensor, cfg.scene.shading,
                                AutoExposureSpec(target=ae.target, metering_scale=0.25))
        assert low == pytest.approx(full, rel=0.05)


def test_controller_is_off_by_default_and_round_trips() -> None:
    ae = config_from_dict(_step_doc()).sensor.auto_exposure
    assert ae is not None and not ae.controlled
    cfg = config_from_dict(_step_doc(time_constant_s=0.3, max_step_stops=1.0))
    assert config_from_dict(config_to_dict(cfg)) == cfg


@pytest.mark.parametrize(("ae", "key"), [
    ({"time_constant_s": -1.0}, "sensor.auto_exposure.time_constant_s"),
    ({"max_step_stops": 0.0}, "sensor.auto_exposure.max_step_stops"),
    ({"metering_scale": 1.5}, "sensor.auto_exposure.metering_scale"),
])
def test_controller_config_errors_name_the_key(ae: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as info:
        config_from_dict(_step_doc(**ae))
    assert "\n" not in str(info.value) and key in str(info.value)


def test_a_controller_over_sparse_samples_is_refused() -> None:
    """motion.every > 1 skips the camera frames between samples: a controller there would expose each
    frame for the scene of the sample before it (seconds old), so the config refuses it in one line."""
    doc = _step_doc(time_constant_s=0.3)
    sparse = {**doc, "motion": {**_STEP_MOTION, "every": 2}}
    with pytest.raises(ConfigError, match=r"motion.every 2.*0.2 s apart") as info:
        config_from_dict(sparse)
    assert "\n" not in str(info.value)
    config_from_dict({**sparse, "sensor": _step_doc()["sensor"]})  # each frame metering itself is fine
    config_from_dict(doc)  # and so is the controller over consecutive frames
