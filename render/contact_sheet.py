"""A contact sheet of sample frames: one per camera preset and lighting preset.

Each tile is a whole frame shrunk to fit, with an inset at native resolution
(enlarged, nearest neighbour) around the red bow beacon, so the glow, colour and
noise are visible. ``python -m deckpose.render.contact_sheet reports/contact_sheet.png``;
``--config configs/realistic_ship.yaml`` takes that config's ``scene`` and ``ship_lights``
sections (the ship look and the ship's own lights);
shading is ``flat`` at night and dusk and ``pbr`` by day either way. ``--height-m`` sets the
camera height (30 m).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from deckpose.render.config import config_from_dict, load_config
from deckpose.render.frame import render_frame
from deckpose.render.plan import FrameSpec
from deckpose.render.scene import DeckRenderer
from deckpose.render.scene_config import Lighting, Shading

from deckpose.atomic_io import atomic_path
from deckpose.camera import preset_names
from deckpose.errors import DeckposeError
from deckpose.pose import ShipPose

PRESETS = ("4mp", "8mp", "16mp", "64mp")


def contact_sheet(presets: tuple[str, ...] = PRESETS, *, tile_w: int = 480, height_m: float = 30.0,
                  seed: int = 1, scene: dict[str, Any] | None = None,
                  ship_lights: dict[str, Any] | None = None) -> np.ndarray:
    """Render the sheet; returns a BGR uint8 image (rows = presets, columns = lighting).

    ``scene``: a config's ``scene`` section (YAML data) instead of the default scene (its
    shading is replaced: ``flat`` at night and dusk, ``pbr`` by day); ``ship_lights``: a config's
    ``ship_lights`` section (navigation lights, floodlights, glints), none without it.
    """
    doc: dict[str, Any] = {"cameras": [{"preset": p} for p in presets], "heights_m": [height_m],
                           "lighting": [x.value for x in Lighting], "seed": seed}
    if scene is not None:
        doc["scene"] = {**scene, "shading": "flat"}
    if ship_lights is not None:
        doc["ship_lights"] = ship_lights
    cfg = config_from_dict(doc)
    pbr = dataclasses.replace(cfg, scene=dataclasses.replace(cfg.scene, shading=Shading.PBR))
    flat_r = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
    pbr_r = DeckRenderer(pbr.layout, pbr.scene, pbr.deck_half_size_m(), pbr.backend)
    ship = ShipPose(np.radians(4.0), np.radians(-2.5), np.radians(12.0), 0.5, 0.8, -0.6)
    rows = []
    for name, cam in cfg.cameras_by_name().items():
        tiles = []
        for light in Lighting:
            c, r = (pbr, pbr_r) if light is Lighting.DAY else (cfg, flat_r)
            rf = render_frame(c, FrameSpec(0, name, height_m, ship, (), 0.0, light, seed), cam, r)
            img = np.ascontiguousarray(rf.frame.image[..., ::-1])
            th = round(tile_w * cam.height_px / cam.width_px)
            tile = cv2.resize(img, (tile_w, th), interpolation=cv2.INTER_AREA)
            u, v = (round(x) for x in rf.truth.points_px[cfg.layout.bow_id])
            k = int(max(8.0, 2.5 * rf.truth.apparent_radius_px[cfg.layout.bow_id] + 6))
            crop = img[max(v - k, 0): v + k, max(u - k, 0): u + k]
            inset = cv2.resize(crop, (110, 110), interpolation=cv2.INTER_NEAREST)
            tile[-inset.shape[0] - 4: -4, -inset.shape[1] - 4: -4] = inset
            cv2.rectangle(tile, (tile_w - inset.shape[1] - 5, th - inset.shape[0] - 5), (tile_w - 4, th - 4),
                          (255, 255, 255), 1)
            label = f"{cam.name}  {light.value} ({c.scene.shading.value})  h={height_m:g} m"
            (tw, _), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1)
            cv2.rectangle(tile, (2, 4), (10 + tw, 24), (0, 0, 0), -1)  # readable on a bright deck
            cv2.putText(tile, label, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(cv2.copyMakeBorder(tile, 2, 2, 2, 2, cv2.BORDER_CONSTANT, value=(40, 40, 40)))
        h = max(t.shape[0] for t in tiles)
        rows.append(np.hstack([cv2.copyMakeBorder(t, 0, h - t.shape[0], 0, 0, cv2.BORDER_CONSTANT) for t in tiles]))
    return np.vstack(rows)


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (2 and one line on stderr for bad input)."""
    from deckpose.cli import exit_codes  # the command line's package: not imported with the module

    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("out", type=Path, nargs="?", default=Path("reports/contact_sheet.png"),
                    help="the PNG to write (default: %(default)s, the committed sheet: give another path "
                         "to keep it); put it before --presets, which takes every word after it")
    ap.add_argument("--presets", nargs="+", default=list(PRESETS), metavar="PRESET",
                    help=f"camera presets, one row each (default: %(default)s; any of {', '.join(preset_names())})")
    ap.add_argument("--height-m", type=float, default=30.0,
                    help="camera height above the deck, metres (default: %(default)s; the committed sheet: 50)")
    ap.add_argument("--config", type=Path, default=None,
                    help="a render config whose scene section (ship, sea, light pools, bloom) and ship_lights "
                         "section (navigation lights, floodlights, glints) the sheet uses")
    args = ap.parse_args(argv)
    try:
        scene = lights = None
        if args.config is not None:
            from deckpose.render.config import config_to_dict

            doc = config_to_dict(load_config(args.config))
            scene, lights = doc["scene"], doc["ship_lights"]
        sheet = contact_sheet(tuple(args.presets), height_m=args.height_m, scene=scene, ship_lights=lights)
        with atomic_path(args.out) as tmp:
            cv2.imwrite(str(tmp), sheet)
    except (DeckposeError, OSError) as exc:
        print(f"contact_sheet: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return exit_codes.USAGE
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]})")
    return exit_codes.OK


if __name__ == "__main__":
    raise SystemExit(main())
