"""Last checks on every estimate: a pose must show the camera the deck's lit side.

The beacons shine up from the deck. A pose whose deck normal points away from the
camera (the camera would look at the deck's underside, where there are no lights)
fits the points only because their order is mirrored or their ids are wrong:
``pnp`` returned such poses (roll 174-180 deg) as ok for every mirrored frame. Such
an estimate is not ok. Angles are also wrapped into [-180, 180) deg, so no
estimator reports a pitch of 359.75 deg.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from deckpose.records import PoseEstimate

__all__ = ["check_poses", "lit_side_towards_camera"]


def _wrap(a: float) -> float:
    """``a`` in [-pi, pi), radians; an angle already there is kept bit for bit."""
    if not math.isfinite(a) or -math.pi <= a < math.pi:
        return a
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def lit_side_towards_camera(est: PoseEstimate) -> bool:
    """Whether the deck normal of ``est`` points toward the camera.

    The camera sits ``height_m`` above the deck centre and ``(-surge, -sway)`` beside
    it (world frame); the deck normal is the third column of ``Rz(yaw) Ry(pitch)
    Rx(roll)``. Missing surge/sway (the thesis method) count as zero.
    """
    cr, sr = math.cos(est.roll_rad), math.sin(est.roll_rad)
    cp, sp = math.cos(est.pitch_rad), math.sin(est.pitch_rad)
    cy, sy = math.cos(est.yaw_rad), math.sin(est.yaw_rad)
    n = (cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr)
    sx = est.surge_m if math.isfinite(est.surge_m) else 0.0
    sw = est.sway_m if math.isfinite(est.sway_m) else 0.0
    return n[0] * -sx + n[1] * -sw + n[2] * est.height_m > 0.0


def check_poses(estimates: Sequence[PoseEstimate]) -> list[PoseEstimate]:
    """``estimates`` with angles wrapped and lit-side-away poses made not ok."""
    out = []
    for e in estimates:
        if e.ok:
            angles = (_wrap(e.roll_rad), _wrap(e.pitch_rad), _wrap(e.yaw_rad))
            if angles != (e.roll_rad, e.pitch_rad, e.yaw_rad):  # (a new record only then)
                e = dataclasses.replace(e, roll_rad=angles[0], pitch_rad=angles[1],
                                        yaw_rad=angles[2])
            if not lit_side_towards_camera(e):
                e = dataclasses.replace(e, ok=False, reason=(
                    f"upside-down deck: the pose (roll {math.degrees(e.roll_rad):.1f} deg, "
                    f"pitch {math.degrees(e.pitch_rad):.1f} deg, height {e.height_m:.2f} m) turns "
                    "the deck's lit side away from the camera; the beacon order is mirrored or "
                    "the ids are wrong"))
        out.append(e)
    return out
