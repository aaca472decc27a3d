"""``pbr`` shading's lean shader (render/sun_shader.py) against pyrender's own ``mesh.frag``.

pyrender's shader is the independent computation: the same scene, camera and sun drawn
through both must agree to rounding where the sun is unshadowed, and the shadows must
cover the same pixels up to the shadow edges (pyrender blurs them over 3 shadow-map
texels, ours over 1).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.ndimage as ndi
import trimesh
from deckpose.render.config import Lighting
from deckpose.render.scene import DeckRenderer
from deckpose.render.sun_shader import SUN_LIT_FRAG, SUN_LIT_VERT

from deckpose.pose import CameraPose, ShipPose

from .conftest import tiny_config

SHIP = {"hull": True, "superstructure": True}


def _pbr_config(*, shadows: bool, waves: int):
    """The tiny config with the ship, under ``pbr``, with or without sun shadows."""
    return tiny_config(scene={"shading": "pbr", "texture_px": 256, "ship": SHIP, "sea": {"waves": waves},
                              "shadows": shadows})


def _both(renderer: DeckRenderer, cfg, lighting: Lighting, pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
    """(ours, pyrender's) raster of one frame of the deck and the ship."""
    import pyrender

    cam = cfg.cameras_by_name()["4mp-320x240"]
    ship = ShipPose(0.04, -0.03, 0.3, 0.5, -0.4)
    ours = renderer.render(cam, pose, ship, 2.0, lighting).copy()
    gl = renderer.offscreen(cam.width_px, cam.height_px)._renderer
    lean = gl.deckpose_sun_programs
    gl.deckpose_sun_programs = pyrender.shader_program.ShaderProgramCache()  # pyrender's mesh.frag
    try:
        theirs = renderer.render(cam, pose, ship, 2.0, lighting).copy()
    finally:
        gl.deckpose_sun_programs = lean
    return ours, theirs


@pytest.mark.parametrize("lighting", [Lighting.DAY, Lighting.DUSK, Lighting.NIGHT])
def test_unshadowed_pbr_frames_match_pyrenders_shader(egl_renderer_factory, lighting: Lighting) -> None:
    cfg = _pbr_config(shadows=False, waves=4)
    ours, theirs = _both(egl_renderer_factory(cfg), cfg, lighting, CameraPose.nadir(30.0))
    diff = np.abs(ours.astype(int) - theirs.astype(int))
    assert theirs.std() > 5  # a scene, not a blank
    # float32 rounding of the same terms: one 8-bit step at most
    assert diff.max() <= 1, diff.max()


@pytest.mark.parametrize("waves", [0, 4])  # the flat sea, and the wave grid re-made each frame
def test_shadows_fall_where_pyrenders_do(egl_renderer_factory, waves: int) -> None:
    lit = _pbr_config(shadows=False, waves=waves)
    shaded = _pbr_config(shadows=True, waves=waves)
    # over the lee side (the sun travels to +x +y): the ship's shadow on the sea in view, and the
    # whole view inside the shadow map (render/scene.py frames the ship, shadow_frame_m; beyond
    # the map pyrender's shader wraps around it and can shade the sea with a ghost of the ship's
    # shadow, ours calls it lit)
    pose = CameraPose.nadir(40.0, x_m=25.0, y_m=20.0)
    no_shadow, _ = _both(egl_renderer_factory(lit), lit, Lighting.DAY, pose)
    ours, theirs = _both(egl_renderer_factory(shaded), shaded, Lighting.DAY, pose)
    drop_ours = no_shadow.astype(int).sum(-1) - ours.astype(int).sum(-1)
    drop_theirs = no_shadow.astype(int).sum(-1) - theirs.astype(int).sum(-1)
    in_theirs, in_ours = drop_theirs > 30, drop_ours > 30  # clearly shadowed pixels (full: ~55)
    assert in_theirs.sum() > 80  # the superstructure's shadow on the foredeck and the hull's side
    # each clearly shadowed pixel of one lies within 2 px of the other's shadow or penumbra
    # (pyrender's PCF spreads a thin shadow over 3 texels, so it may only darken it partly)
    near_theirs = ndi.binary_dilation(drop_theirs > 5, iterations=2)
    near_ours = ndi.binary_dilation(drop_ours > 5, iterations=2)
    assert not (in_ours & ~near_theirs).any() and not (in_theirs & ~near_ours).any()
    lit = ~(near_theirs | near_ours)
    assert lit.mean() > 0.8  # most of the frame is compared
    # far from shadows: untouched, but for a faint penumbra's last steps (no shadow acne)
    faint = np.abs(ours[lit].astype(int) - no_shadow[lit].astype(int))
    assert faint.max() <= 2 and (faint > 0).mean() < 1e-3


def test_the_shader_ships_with_the_package() -> None:
    for path in (SUN_LIT_FRAG, SUN_LIT_VERT):
        assert path.is_file() and path.read_text().startswith("#version 330 core")


@pytest.mark.parametrize(("ship", "pose"), [
    # over the lee side of the ship (the sun travels to +x +y)
    (ShipPose(0.04, -0.03, 0.3, 0.5, -0.4), CameraPose.nadir(60.0, x_m=25.0, y_m=20.0)),
    # the bow turned to the far corner: its shadow lies 60 m out (a 120 m map around the scene's
    # centre had missed it)
    (ShipPose(0.043, -0.019, 2.308, 0.26, 0.62, -0.32), CameraPose.nadir(71.0, x_m=-19.0, y_m=45.0)),
    (ShipPose(-0.12, 0.1, -1.2, -0.5, 0.3, 0.6), CameraPose.nadir(45.0, x_m=20.0, y_m=-30.0)),
])
def test_shadows_on_the_sea_match_ray_casting(egl_renderer_factory, ship: ShipPose, pose: CameraPose) -> None:
    """Independent: a sea pixel is shadowed exactly where the segment from its sea point toward the
    sun crosses the ship (hull, superstructure, deck plate: trimesh geometry, brute-force ray casts)."""
    from deckpose.render.scene import SUN_TRAVEL_WORLD
    from deckpose.render.ship_model import hull_mesh, superstructure_mesh

    from .test_ship_scene import _hits

    lit = _pbr_config(shadows=False, waves=0)
    shaded = _pbr_config(shadows=True, waves=0)
    cam = lit.cameras_by_name()["4mp-320x240"]
    no_shadow = egl_renderer_factory(lit).render(cam, pose, ship, 2.0, Lighting.DAY).astype(int).sum(-1)
    with_shadow = egl_renderer_factory(shaded).render(cam, pose, ship, 2.0, Lighting.DAY).astype(int).sum(-1)
    shadowed = no_shadow - with_shadow > 10  # the sun's share of the dark sea: 28-72 (sum of R, G, B)

    a, freeboard = lit.deck_half_size_m(), lit.scene.freeboard_m
    plate = trimesh.Trimesh([[-a, -a, 0], [a, -a, 0], [a, a, 0], [-a, a, 0]], [[0, 1, 2], [0, 2, 3]])
    ship_m = trimesh.util.concatenate([hull_mesh(a, freeboard), superstructure_mesh(a), plate])
    ship_m.apply_transform(ship.T_world_from_deck)
    # each sampled pixel's centre and 4 points 1 px away: a pixel counts only where all 5 agree
    vv, uu = np.mgrid[2:cam.height_px - 2:4, 2:cam.width_px - 2:4]
    offsets = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]], float)
    px = np.concatenate([np.column_stack([uu.ravel() + du, vv.ravel() + dv]) for du, dv in offsets])
    rays = pose.R_world_from_cam @ np.linalg.solve(cam.K, np.column_stack([px, np.ones(len(px))]).T)
    origin = pose.position_world_m
    sea_m = origin[None] + rays.T * ((-freeboard - origin[2]) / rays[2])[:, None]  # on the sea plane
    seen = ~_hits(ship_m, np.broadcast_to(origin, sea_m.shape), sea_m)
    in_shadow = _hits(ship_m, sea_m, sea_m - 200.0 * SUN_TRAVEL_WORLD[None])
    seen, in_shadow = seen.reshape(5, -1).all(0), in_shadow.reshape(5, -1)
    sure = seen & (in_shadow.all(0) | ~in_shadow.any(0))
    want = in_shadow[0][sure]
    got = shadowed[vv.ravel(), uu.ravel()][sure]
    assert want.sum() > 20  # the ship's shadow lies on the sea in view
    np.testing.assert_array_equal(got, want)


def test_tiled_shadowed_frame_equals_single_pass(egl_renderer_factory, monkeypatch: pytest.MonkeyPatch) -> None:
    """A frame drawn in 4 tiles draws its shadow map once (for the first tile) and reuses it: the
    same shadows as one draw."""
    import deckpose.render.scene as scene_mod

    cfg = _pbr_config(shadows=True, waves=0)
    r = egl_renderer_factory(cfg)
    cam = cfg.cameras_by_name()["4mp-320x240"]
    args = (cam, CameraPose.nadir(60.0, x_m=25.0, y_m=20.0), ShipPose(0.04, -0.03, 0.3, 0.5, -0.4), 2.0,
            Lighting.DAY)
    other = (cam, CameraPose.nadir(40.0), ShipPose(-0.05, 0.04, 1.9, 0.2, 3.0, -2.0), 0.0, Lighting.DAY)
    whole = r.render(*args).astype(int)
    r.render(*other)  # another ship pose: the tiled frame must draw its own map, on its first tile
    passes: list[int] = []
    own_pass = type(r.offscreen(8, 8)._renderer)._shadow_mapping_pass
    monkeypatch.setattr(type(r.offscreen(8, 8)._renderer), "_shadow_mapping_pass",
                        lambda self, *a: (passes.append(1), own_pass(self, *a))[1])
    monkeypatch.setattr(scene_mod, "MAX_TILE_PX", 320 * 70)  # 4 tiles of 60 rows
    tiled = r.render(*args).astype(int)
    assert len(passes) == 1
    diff = np.abs(whole - tiled)
    assert diff.mean() < 0.05 and diff.max() <= 3  # as test_scene's unshadowed tiles


OSMESA_TWO_SIZES = """
import numpy as np
from deckpose.render.config import Lighting, config_from_dict
from deckpose.render.scene import DeckRenderer
from deckpose.camera import CameraModel
from deckpose.pose import CameraPose, ShipPose
doc = {"backend": "osmesa", "cameras": [{"preset": "4mp", "size": [320, 240]}], "heights_m": [30.0],
       "scene": {"shading": "pbr", "texture_px": 256, "ship": {"hull": True, "superstructure": True},
                 "sea": {"waves": 2}, "shadows": True}}
cfg = config_from_dict(doc)
r = DeckRenderer(cfg.layout, cfg.scene, cfg.deck_half_size_m(), cfg.backend)
big = cfg.cameras_by_name()["4mp-320x240"]
small = CameraModel(160, 120, big.K * [[0.5], [0.5], [1.0]])
args = (CameraPose.nadir(60.0, x_m=25.0, y_m=20.0), ShipPose(0.04, -0.03, 0.3, 0.5, -0.4), 2.0, Lighting.DAY)
first = r.render(big, *args).copy()
r.render(small, *args)
again = r.render(big, *args).copy()
r.render(small, *args)
print("max diff", int(np.abs(first.astype(int) - again.astype(int)).max()), "mean", float(first.mean()))
"""


def test_osmesa_pbr_shadows_survive_a_change_of_size() -> None:
    """OSMesa re-makes its context at each new size: the frame drawn after a smaller one is the
    same, and nothing fails (a worker process: this one uses EGL)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYOPENGL_PLATFORM": "osmesa"}
    out = subprocess.run([sys.executable, "-c", OSMESA_TWO_SIZES], env=env, capture_output=True, text=True, check=False,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "Error" not in out.stderr, out.stderr[-2000:]
    assert "max diff 0 " in out.stdout, out.stdout
