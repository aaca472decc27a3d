"""``deckpose crb``: the Cramér–Rao bound on roll, pitch, yaw, surge, sway and height."""

from __future__ import annotations

import argparse
import json
import math


def register(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "crb",
        help="Cramér–Rao bound of the pose for a layout, camera, pose and pixel noise",
        description=(
            "Print the Cramér–Rao lower bound on the standard deviation of each pose "
            "parameter (degrees and metres) for Gaussian pixel noise of SIGMA px on every "
            "visible beacon. The camera sits HEIGHT m above the deck centre, looking down "
            "(optionally tilted), with its attitude known."
        ),
    )
    p.add_argument("--camera", default="8mp",
                   help="camera preset (4mp, 8mp, 16mp, 64mp[-thesis|-square], published) "
                        "or a camera_info YAML file (default: 8mp)")
    p.add_argument("--layout", default=None, help="layout YAML file (default: 12-beacon ring + centre)")
    p.add_argument("--no-centre", action="store_true", help="drop the centre beacon from the layout")
    p.add_argument("--height-m", type=float, default=20.0, help="camera height above the deck centre")
    p.add_argument("--roll-deg", type=float, default=0.0, help="deck ZYX roll")
    p.add_argument("--pitch-deg", type=float, default=0.0, help="deck ZYX pitch")
    p.add_argument("--yaw-deg", type=float, default=0.0, help="deck ZYX yaw")
    p.add_argument("--surge-m", type=float, default=0.0, help="deck-centre offset along world x")
    p.add_argument("--sway-m", type=float, default=0.0, help="deck-centre offset along world y")
    p.add_argument("--camera-tilt-deg", type=float, nargs=2, default=(0.0, 0.0), metavar=("ABOUT_X", "ABOUT_Y"),
                   help="camera tilt from nadir about its own x and y axes, degrees")
    p.add_argument("--sigma-px", type=float, nargs="+", default=[0.5],
                   help="pixel noise standard deviation(s), px (default 0.5)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from deckpose.camera import preset
    from deckpose.camera_info import read_camera_info
    from deckpose.errors import ConfigError
    from deckpose.estimate.crb import cramer_rao_bound
    from deckpose.layout import DeckLayout, read_layout
    from deckpose.pose import CameraPose, ShipPose
    from deckpose.rotation import rot_x, rot_y

    camera = read_camera_info(args.camera) if Path(args.camera).suffix in (".yaml", ".yml") else preset(args.camera)
    layout = read_layout(args.layout) if args.layout else DeckLayout()
    if args.no_centre:
        import dataclasses
        layout = dataclasses.replace(layout, has_centre=False)
    for s in args.sigma_px:
        if not s > 0:
            raise ConfigError(f"--sigma-px must be positive, got {s}")
    ship = ShipPose(math.radians(args.roll_deg), math.radians(args.pitch_deg), math.radians(args.yaw_deg),
                    0.0, args.surge_m, args.sway_m)
    tx, ty = (math.radians(a) for a in args.camera_tilt_deg)
    cam_pose = CameraPose.nadir(args.height_m, R_nadir_from_cam=np.asarray(rot_x(tx) @ rot_y(ty)))
    rows = []
    for s in args.sigma_px:
        b = cramer_rao_bound(layout, camera, ship, cam_pose, s)
        sig = b.sigma
        rows.append({
            "sigma_px": s, "n_beacons": len(b.visible_ids),
            "roll_deg": math.degrees(sig["roll_rad"]), "pitch_deg": math.degrees(sig["pitch_rad"]),
            "yaw_deg": math.degrees(sig["yaw_rad"]), "surge_m": sig["surge_m"],
            "sway_m": sig["sway_m"], "height_m": sig["height_m"],
            "determined": b.ok,
        })
    if args.json:
        # strict JSON: a bound the beacons do not determine is null, not NaN
        plain = [{k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in r.items()}
                 for r in rows]
        print(json.dumps({"camera": camera.name, "height_m": args.height_m, "bounds": plain}, indent=2,
                         allow_nan=False))
        return 0
    print(f"Cramér–Rao bound (1 sigma) — camera {camera.name or args.camera}, "
          f"height {args.height_m:g} m, ring {layout.n_ring} r={layout.radius_m:g} m"
          f"{' + centre' if layout.has_centre else ''}")
    head = ("sigma_px", "beacons", "roll_deg", "pitch_deg", "yaw_deg", "surge_m", "sway_m", "height_m")
    print("  ".join(f"{h:>10}" for h in head))
    for r in rows:
        vals = [f"{r['sigma_px']:>10g}", f"{r['n_beacons']:>10d}"] + [
            f"{r[k]:>10.3g}" for k in head[2:]]
        print("  ".join(vals))
    n_seen = rows[0]["n_beacons"]
    if not all(r["determined"] for r in rows):
        print(f"nan: the {n_seen} beacon(s) in view do not determine the pose (it takes at least 4, not all "
              "on one line); raise --height-m, or tilt the camera toward the deck (--camera-tilt-deg)")
    return 0
