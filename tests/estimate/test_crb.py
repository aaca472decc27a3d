import json

import numpy as np
import pytest
from deckpose.estimate import registry
from deckpose.estimate.crb import cramer_rao_bound
from deckpose.estimate.registry import EstimateOptions

from deckpose.camera import preset
from deckpose.cli import main
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.rotation import rot_x
from tests.estimate.synthetic import detections_for

SHIP = ShipPose(0.04, -0.06, 0.7, 0.0, 0.5, 1.0)


def test_crb_of_a_single_point_pair_by_hand():
    """Level deck, nadir, square pixels: height bound by hand from d(u)/d(h) of each beacon.

    With only height free, a ring beacon at radius r images at f*r/h from the centre,
    so d/dh = -f*r/h^2 per ring beacon; the information is n*(f r/h^2)^2/sigma^2. The full
    6x6 bound on height must be at least that 1-parameter bound (and equal here, since
    height decouples from the other parameters for a symmetric ring at nadir).
    """
    cam = preset("8mp-square")
    h, s = 40.0, 0.5
    b = cramer_rao_bound(DeckLayout(), cam, ShipPose(), CameraPose.nadir(h), s)
    f, r = cam.fx, 10.0
    one_param = s / np.sqrt(12 * (f * r / h**2) ** 2)
    assert b.sigma["height_m"] == pytest.approx(one_param, rel=1e-9)


def test_crb_scales_with_sigma_and_equals_estimator_covariance_at_truth():
    cam = preset("16mp")
    pose = CameraPose.nadir(30.0, R_nadir_from_cam=rot_x(0.1))
    b1 = cramer_rao_bound(DeckLayout(), cam, SHIP, pose, 0.5)
    b2 = cramer_rao_bound(DeckLayout(), cam, SHIP, pose, 2.0)
    np.testing.assert_allclose(b2.covariance, 16 * b1.covariance, rtol=1e-9)
    det = detections_for(DeckLayout(), SHIP, pose, cam)   # exact points, cov 0.25 px^2 = 0.5 px
    est = registry.get("pnp")(det, cam, DeckLayout(), EstimateOptions(R_world_from_cam=pose.R_world_from_cam))
    np.testing.assert_allclose(est.covariance, b1.covariance, rtol=1e-6)


def test_crb_rejects_bad_sigma():
    with pytest.raises(ConfigError):
        cramer_rao_bound(DeckLayout(), preset("4mp"), SHIP, CameraPose.nadir(20.0), 0.0)


def test_crb_cli_table_and_json(capsys):
    assert main(["crb", "--camera", "4mp", "--height-m", "40", "--sigma-px", "0.5", "2", "--roll-deg", "3"]) == 0
    out = capsys.readouterr().out
    assert "roll_deg" in out and len(out.strip().splitlines()) == 4
    assert main(["crb", "--json", "--sigma-px", "1", "--camera-tilt-deg", "5", "0"]) == 0
    doc = json.loads(capsys.readouterr().out)
    b = cramer_rao_bound(DeckLayout(), preset("8mp"), ShipPose(), CameraPose.nadir(20.0, R_nadir_from_cam=rot_x(np.radians(5))), 1.0)
    assert doc["bounds"][0]["roll_deg"] == pytest.approx(np.degrees(b.sigma["roll_rad"]), rel=1e-9)
    assert main(["crb", "--sigma-px", "-1"]) == 2


def test_crb_cli_says_why_a_bound_is_undetermined(capsys):
    """At 1 m only the centre beacon is in view: the table's nan is explained, and --json is strict JSON."""
    assert main(["crb", "--height-m", "1"]) == 0
    out = capsys.readouterr().out
    assert "do not determine the pose" in out and "raise --height-m" in out
    assert main(["crb", "--height-m", "1", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"{c} is not JSON"))
    assert doc["bounds"][0]["determined"] is False and doc["bounds"][0]["roll_deg"] is None
    assert main(["crb", "--height-m", "30"]) == 0
    assert "do not determine" not in capsys.readouterr().out
