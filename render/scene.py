"""The rasterised part of a frame: the deck plate and the sea, through pyrender.

What is rasterised and what is not
----------------------------------
pyrender draws the deck (a textured plate with a helipad circle, lines and a
non-skid texture) and the sea (a large tiled, drifting texture) with 4x MSAA.
The beacons are *not* rasterised: :mod:`deckpose.render.beacons` splats them
analytically at their exact projected positions, because a rasterised
sub-pixel emitter is only as good as the rasteriser's coverage sampling
(4 samples per pixel gives centroid errors of several hundredths of a pixel),
while an analytic splat is exact, costs nothing at 64 MP and is distortion-aware.

Camera convention
-----------------
OpenGL puts pixel centres at ``+0.5`` and its image origin at the bottom-left;
OpenCV puts them at integers, origin top-left. With pyrender's
:class:`~pyrender.IntrinsicsCamera`, OpenGL window coordinates are
``x_w = fx*x/z + cx_gl`` and ``y_w = H - cy_gl + fy*y_gl/(-z_gl)``; pixel ``(col, row)``
samples ``x_w = col + 0.5`` and ``y_w = H - row - 0.5``. So a frame matches
``CameraModel.K`` exactly with ``cx_gl = cx + 0.5`` and ``cy_gl = cy + 0.5``
(tested in ``tests/render/test_scene.py`` to 0.05 px with 4x MSAA).

GL context
----------
:class:`DeckRenderer` creates its context on the first :meth:`~DeckRenderer.render`
call, in the process that renders (a worker), never in a parent; the process has one
(:mod:`deckpose.render.gl_context`, which also holds what we change on pyrender's
renderer). Large frames are
drawn in horizontal tiles (a shifted principal point per tile) so the multisampled
framebuffer stays small: a 64 MP frame needs four 16 MP tiles.
"""

from __future__ import annotations

import math
import os
import sys
import types
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from deckpose.render.config import Backend
from deckpose.render.gl_context import offscreen
from deckpose.render.lens import MAX_SIDE_PX
from deckpose.render.light_pools import AMBIENT_LUX, apply_light_pools, pool_gain
from deckpose.render.scene_config import DEFAULT_TEXTURE_SEED, Lighting, SceneSpec, Shading
from deckpose.render.sea import Waves, sea_colour, sea_grid_m, sea_grid_surface, sea_waves
from deckpose.render.ship_model import hull_mesh, superstructure_mesh
from deckpose.render.sun_shader import sun_program_cache
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

#: OpenCV camera frame to OpenGL camera frame (y and z flipped).
_CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])
#: Largest tile the renderer allocates, pixels: 2^24, so a 64 MP frame (9248 x 6936 = 64.1 M)
#: is four draws (16,000,000 made it five). Its 4x multisampled colour and depth-stencil
#: buffers take 4 x 8 bytes a pixel, 512 MiB. Four draws of a 64 MP frame measured 1.95 s
#: against 2.12 s for five (median of 4 interleaved, llvmpipe, load 0.9 on 2 cores).
MAX_TILE_PX = 2**24
#: The direction the sun's light travels in (world frame, unit): from azimuth 35 degrees (x toward
#: y), 54.5 degrees above the horizon (the same sun for every lighting preset).
SUN_TRAVEL_WORLD = (np.array([math.cos(math.radians(35.0)) * 0.5, math.sin(math.radians(35.0)) * 0.5, -0.7])
                    / math.hypot(0.5, 0.7))
#: Texture seed: the scene is the same in every worker and every run.


@dataclass(frozen=True)
class LightPreset:
    """Light levels of one preset (linear radiance scale, white = 1)."""

    level: float
    tint: tuple[float, float, float]
    sky_rgb: tuple[float, float, float]
    ambient: float
    sun_intensity: float


PRESETS: dict[Lighting, LightPreset] = {
    Lighting.NIGHT: LightPreset(0.04, (0.8, 0.85, 1.0), (0.0, 0.0, 0.01), 0.04, 0.0),
    Lighting.DUSK: LightPreset(0.25, (1.0, 0.78, 0.6), (0.25, 0.15, 0.12), 0.2, 0.8),
    Lighting.DAY: LightPreset(0.85, (1.0, 1.0, 1.0), (0.6, 0.7, 0.85), 0.5, 3.0),
}


def use_backend(backend: Backend) -> None:
    """Select the headless GL platform before pyrender is imported in this process.

    Raises
    ------
    ConfigError
        If OpenGL is already loaded here with another platform.
    """
    want = backend.value
    have = os.environ.get("PYOPENGL_PLATFORM")
    if "OpenGL" in sys.modules and have != want:
        raise ConfigError(
            f"backend {want!r} requested but this process already loaded OpenGL for {have!r}; "
            "render with workers >= 1 (fresh worker processes) to switch backends"
        )
    os.environ["PYOPENGL_PLATFORM"] = want


def gl_intrinsics(camera: CameraModel, row0: int, tile_h: int) -> tuple[float, float, float, float]:
    """``(fx, fy, cx_gl, cy_gl)`` for pyrender's IntrinsicsCamera drawing rows ``row0..row0+tile_h``.

    OpenGL samples pixel centres at ``+0.5`` with rows counted from the bottom, so
    ``cx_gl = cx + 0.5`` and ``cy_gl = cy - row0 + 0.5`` reproduce
    ``camera.K`` (OpenCV, centres at integers) exactly.
    """
    return camera.fx, camera.fy, camera.cx + 0.5, camera.cy - row0 + 0.5


def gl_camera_pose(camera_pose: CameraPose) -> NDArray[np.float64]:
    """pyrender camera-node pose (OpenGL camera: y up, looking along -z), (4, 4)."""
    return camera_pose.T_world_from_cam @ _CV_TO_GL


def deck_texture(layout: DeckLayout, half_size_m: float, size_px: int,
                 seed: int = DEFAULT_TEXTURE_SEED) -> NDArray[np.uint8]:
    """RGB texture of the deck plate: non-skid grey, helipad circle and 'H', edge and centre lines.

    Row 0 is the bow edge (deck +x), column 0 the port edge (deck +y); ``seed`` draws the
    non-skid grain (``scene.texture_seed``).
    """
    rng = np.random.default_rng(seed)
    s = size_px
    base = 0.42 + 0.05 * rng.standard_normal((s // 8, s // 8))
    base = cv2.resize(base.astype(np.float32), (s, s), interpolation=cv2.INTER_CUBIC)
    rows = max(1, 2**20 // s)  # noise in row blocks (the same draws as one call; less memory at 8k)
    for r0 in range(0, s, rows):
        base[r0:r0 + rows] += 0.03 * rng.standard_normal((min(rows, s - r0), s)).astype(np.float32)
    np.clip(base, 0, 1, out=base)
    img = np.empty((s, s, 3), np.uint8)
    for c, tint in enumerate((1.0, 1.0, 0.97)):  # channel by channel: one float32 plane at a time
        img[..., c] = (base * np.float32(tint) * 255).astype(np.uint8)
    px_per_m = s / (2.0 * half_size_m)

    def pt(x_m: float, y_m: float) -> tuple[int, int]:
        return round((half_size_m - y_m) * px_per_m * 16), round((half_size_m - x_m) * px_per_m * 16)

    def w(m: float) -> int:
        return max(1, round(m * px_per_m))

    white, yellow = (235, 235, 230), (230, 200, 40)
    r_pad = 0.6 * layout.radius_m
    cv2.circle(img, pt(0, 0), int(r_pad * px_per_m * 16), yellow, w(0.3), cv2.LINE_AA, 4)
    e = 0.97 * half_size_m
    cv2.rectangle(img, pt(e, e), pt(-e, -e), white, w(0.25), cv2.LINE_AA, 4)
    cv2.line(img, pt(e, 0), pt(r_pad + 0.5, 0), white, w(0.15), cv2.LINE_AA, 4)
    cv2.line(img, pt(-r_pad - 0.5, 0), pt(-e, 0), white, w(0.15), cv2.LINE_AA, 4)
    hh = 0.3 * r_pad
    for y in (hh * 0.6, -hh * 0.6):
        cv2.line(img, pt(hh, y), pt(-hh, y), white, w(0.35), cv2.LINE_AA, 4)
    cv2.line(img, pt(0, hh * 0.6), pt(0, -hh * 0.6), white, w(0.35), cv2.LINE_AA, 4)
    for b in layout.positions_deck_m():  # dark fitting under each beacon
        cv2.circle(img, pt(b[0], b[1]), int(3 * layout.beacon_radius_m * px_per_m * 16), (40, 40, 40),
                   -1, cv2.LINE_AA, 4)
    return img


def sea_texture(size_px: int, seed: int = DEFAULT_TEXTURE_SEED) -> NDArray[np.uint8]:
    """Tileable RGB sea texture (periodic noise, so it repeats without seams); ``seed`` as the deck's."""
    rng = np.random.default_rng(seed + 1)
    s = size_px
    spec = rng.standard_normal((s, s)) + 1j * rng.standard_normal((s, s))
    k = np.fft.fftfreq(s)[:, None] ** 2 + np.fft.fftfreq(s)[None, :] ** 2
    spec *= np.exp(-k * (s / 24.0) ** 2) * (k > 0)
    waves = np.real(np.fft.ifft2(spec))
    waves = (waves - waves.mean()) / (waves.std() + 1e-12)
    base = np.array([0.05, 0.16, 0.24])
    img = base + 0.05 * np.tanh(waves)[..., None] * np.array([0.6, 0.9, 1.0])
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def plane_primitive(half_x: float, half_y: float, z: float, uv_scale: float) -> dict[str, np.ndarray]:
    """A flat rectangle ``2 half_x`` by ``2 half_y`` metres at height ``z``, facing up, as the keyword
    arguments of a :class:`pyrender.Primitive` (texture coordinates scaled by ``uv_scale``)."""
    pos = np.array([[half_x, half_y, z], [-half_x, half_y, z], [-half_x, -half_y, z], [half_x, -half_y, z]],
                   dtype=np.float32)
    uv = np.array([[0, 0], [0, 1], [1, 1], [1, 0]], dtype=np.float32) * uv_scale
    return {"positions": pos, "normals": np.tile(np.array([0, 0, 1], np.float32), (4, 1)), "texcoord_0": uv,
            "indices": np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)}


class DeckRenderer:
    """A pyrender scene of deck and sea with its offscreen renderers (a real GL resource).

    Parameters
    ----------
    layout : DeckLayout
    scene : SceneSpec
    deck_half_size_m : float
    backend : Backend
    """

    def __init__(self, layout: DeckLayout, scene: SceneSpec, deck_half_size_m: float,
                 backend: Backend) -> None:
        self.layout = layout
        self.spec = scene
        self.half_m = deck_half_size_m
        self.backend = backend
        self._pr: Any = None
        self._scene: Any = None
        self._nodes: dict[str, Any] = {}
        self._sea_tile_m = 40.0
        self._waves = sea_waves(scene.sea) if scene.sea.waves > 0 else None
        self._pool_gain: dict[Lighting, NDArray[np.float32]] = {}
        self._sea_mat: Any = None
        self._sea_grid = np.zeros(0)
        self._sea_faces = np.zeros((0, 3), np.uint32)
        self._shadow_centre_deck_m = np.zeros(3)

    def _build(self) -> Any:
        """Make the scene (pyrender's Scene), kept as ``_scene``; returns it."""
        use_backend(self.backend)
        import pyrender

        self._pr = pyrender
        pbr = self.spec.shading is Shading.PBR
        deck_tex = pyrender.Texture(source=deck_texture(self.layout, self.half_m, self.spec.texture_px,
                                                            self.spec.texture_seed),
                                    source_channels="RGB")
        sea_tex = pyrender.Texture(source=sea_texture(512, self.spec.texture_seed), source_channels="RGB",
                                   sampler=pyrender.Sampler(wrapS=10497, wrapT=10497))
        deck_mat = pyrender.MetallicRoughnessMaterial(baseColorTexture=deck_tex, metallicFactor=0.0,
                                                      roughnessFactor=0.8)
        sea_mat = pyrender.MetallicRoughnessMaterial(baseColorTexture=sea_tex, metallicFactor=0.3 if pbr else 0.0,
                                                     roughnessFactor=0.15)
        deck = pyrender.Mesh([pyrender.Primitive(**plane_primitive(self.half_m, self.half_m, 0.0, 1.0), material=deck_mat)])
        L = self.spec.sea_half_size_m
        sea: Any = pyrender.Mesh([pyrender.Primitive(**plane_primitive(L, L, 0.0, 2 * L / self._sea_tile_m), material=sea_mat)])
        sea.deckpose_background = True  # drawn last, casts no shadow (_background_last, _shadow_pass_of_casters)
        s = pyrender.Scene(bg_color=[0, 0, 0, 1], ambient_light=[0.3] * 3)
        self._nodes["deck"] = s.add(deck)
        if self._waves is None:
            self._nodes["sea"] = s.add(sea)
        else:  # the wave grid is re-made each frame (:meth:`_set_wave_sea`)
            self._sea_mat = pyrender.MetallicRoughnessMaterial(metallicFactor=0.3 if pbr else 0.0,
                                                               roughnessFactor=0.12)
            self._sea_grid = sea_grid_m(L)
        ship = self.spec.ship
        hull_mat = pyrender.MetallicRoughnessMaterial(metallicFactor=0.0, roughnessFactor=0.7)
        a = self.half_m
        casters = [np.array([[-a, -a, 0.0], [a, -a, 0.0], [a, a, 0.0], [-a, a, 0.0]])]  # the deck plate
        for name, on, mesh in (("hull", ship.hull, lambda: hull_mesh(self.half_m, self.spec.freeboard_m)),
                               ("superstructure", ship.superstructure, lambda: superstructure_mesh(self.half_m))):
            if on:
                m = mesh()
                casters.append(np.asarray(m.vertices))
                self._nodes[name] = s.add(_solid_mesh(pyrender, m, hull_mat, linear=pbr))
        sun: Any = pyrender.DirectionalLight(color=np.ones(3), intensity=1.0)
        if self.spec.shadows:
            self._shadow_centre_deck_m, sun.deckpose_shadow_half_m = shadow_frame_m(np.vstack(casters))
            sun._get_shadow_camera = types.MethodType(_deck_shadow_camera, sun)
        self._nodes["sun"] = s.add(sun)
        self._scene = s
        return s

    def _renderer(self, width: int, height: int) -> Any:
        return offscreen(self._pr, width, height, self.spec.antialias_samples)

    def offscreen(self, width: int, height: int) -> Any:
        """This renderer's pyrender OffscreenRenderer, sized ``width x height``.

        For drawing other scenes in the same GL context (tests): pyrender's EGL
        platform terminates the process-wide display when a renderer is deleted,
        so a process must keep to one context.
        """
        if self._scene is None:
            self._build()
        return self._renderer(width, height)

    def render(self, camera: CameraModel, camera_pose: CameraPose, ship: ShipPose, t_s: float,
               lighting: Lighting) -> NDArray[np.uint8]:
        """Rasterise deck and sea for one frame (undistorted pinhole image through ``camera.K``).

        Returns
        -------
        (H, W, 3) array of uint8
            Display-referred RGB; :func:`radiance_scale` turns it into radiance.
        """
        s = self._build() if self._scene is None else self._scene
        pr = self._pr
        light = PRESETS[lighting]
        pbr = self.spec.shading is Shading.PBR
        s.set_pose(self._nodes["deck"], ship.T_world_from_deck)
        for name in ("hull", "superstructure"):
            if name in self._nodes:
                s.set_pose(self._nodes[name], ship.T_world_from_deck)
        if self._waves is None:
            drift = (self.spec.sea_drift_m_per_s * t_s) % self._sea_tile_m
            T_sea = np.eye(4)
            T_sea[:3, 3] = [drift, 0.3 * drift, -self.spec.freeboard_m]
            s.set_pose(self._nodes["sea"], T_sea)
        s.bg_color = np.array([*light.sky_rgb, 1.0]) * (1.0 if pbr else 1.0 / max(light.level, 1e-6))
        s.ambient_light = np.full(3, light.ambient) * np.array(light.tint)
        sun = self._nodes["sun"]
        sun.light.intensity = light.sun_intensity
        sun.light.color = np.array(light.tint)
        z = -SUN_TRAVEL_WORLD
        x = np.cross([0.0, 0.0, 1.0], z)
        x /= np.linalg.norm(x)
        T_sun = np.eye(4)
        T_sun[:3, :3] = np.stack([x, np.cross(z, x), z], 1)
        s.set_pose(sun, T_sun)
        if self._waves is not None:
            sky = np.asarray(light.sky_rgb) * (1.0 if pbr else 1.0 / max(light.level, 1e-6))
            self._set_wave_sea(self._waves, camera_pose.position_world_m, t_s, sky, None if pbr else z)
        flags = 0 if pbr else pr.RenderFlags.FLAT
        if pbr and self.spec.shadows and light.sun_intensity > 0:
            flags |= pr.RenderFlags.SHADOWS_DIRECTIONAL
        W, H = camera.width_px, camera.height_px
        # tiles small enough for the MSAA buffers and no taller than OpenGL's side limit
        n_tiles = max(1, math.ceil(W * H / MAX_TILE_PX), math.ceil(H / MAX_SIDE_PX))
        tile_h = math.ceil(H / n_tiles)
        out = np.empty((H, W, 3), np.uint8)
        T_cam = gl_camera_pose(camera_pose)
        shadow_centre = ship.T_world_from_deck[:3, :3] @ self._shadow_centre_deck_m + ship.T_world_from_deck[:3, 3]
        far = 2.5 * self.spec.sea_half_size_m
        for k in range(n_tiles):
            r0 = k * tile_h
            r1 = min(H, r0 + tile_h)
            cam = pr.IntrinsicsCamera(*gl_intrinsics(camera, r0, tile_h), znear=0.2, zfar=far)
            node = s.add(cam, pose=T_cam)
            s.main_camera_node = node
            renderer = self._renderer(W, tile_h)
            gl = renderer._renderer  # OSMesa re-made it in offscreen() if the size changed; render() keeps it
            rows = out[r0:r1]
            own_programs = gl._program_cache
            try:
                gl.deckpose_read_into = rows  # read back straight into the frame
                gl.deckpose_shadow_map_drawn = k > 0  # one shadow pass a frame, not one a tile
                gl.deckpose_shadow_centre = shadow_centre
                if pbr:  # the sun's lean shaders in place of pyrender's mesh.vert/.frag (render/sun_shader.py)
                    if getattr(gl, "deckpose_sun_programs", None) is None:
                        gl.deckpose_sun_programs = sun_program_cache(pr)
                    gl._program_cache = gl.deckpose_sun_programs
                color, _ = renderer.render(s, flags=flags)
            finally:
                s.remove_node(node)
                gl.deckpose_read_into = None
                gl.deckpose_shadow_centre = None
                gl.deckpose_shadow_map_drawn = False
                gl._program_cache = own_programs
                del gl  # keep no Renderer alive into the next tile (OSMesa may re-make it)
            if color is not rows:  # a platform without framebuffers reads through pyrender
                rows[:] = color[: r1 - r0]
        if self.spec.light_pools_cd > 0 and lighting is not Lighting.DAY:
            if lighting not in self._pool_gain:
                self._pool_gain[lighting] = pool_gain(self.layout, self.half_m, self.spec.light_pools_cd,
                                                      AMBIENT_LUX[lighting])
            apply_light_pools(out, self._pool_gain[lighting], self.half_m, camera, camera_pose, ship)
        return out

    def _set_wave_sea(self, sea: tuple[Waves, Waves], camera_m: NDArray[np.float64], t_s: float,
                      sky_rgb: NDArray[np.float64], sun_dir: NDArray[np.float64] | None) -> None:
        """Replace the sea node by the wave grid at ``t_s`` (heights, normals, Fresnel colours)."""
        g = self._sea_grid
        n = len(g)
        if self._sea_faces.shape[0] == 0:  # the grid's triangles, made once
            i = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
            self._sea_faces = np.concatenate([np.column_stack([i, i + n, i + n + 1]),
                                              np.column_stack([i, i + n + 1, i + 1])]).astype(np.uint32)
        eta, normals = sea_grid_surface(*sea, g, t_s)
        pos = np.column_stack([np.repeat(g, n), np.tile(g, n), eta - self.spec.freeboard_m])
        to_cam = camera_m[None, :] - pos
        to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
        rgb = sea_colour(normals, to_cam, sky_rgb, sun_dir)
        if sun_dir is None:  # pbr: pyrender lights linear colours and encodes its output
            rgb = srgb_to_linear(rgb)
        colour = np.column_stack([rgb, np.ones(len(rgb))]).astype(np.float32)
        prim = self._pr.Primitive(positions=pos.astype(np.float32), normals=normals.astype(np.float32),
                                  color_0=colour, indices=self._sea_faces, material=self._sea_mat)
        if "sea" in self._nodes:
            self._scene.remove_node(self._nodes["sea"])
        mesh = self._pr.Mesh([prim])
        mesh.deckpose_background = True  # drawn last, casts no shadow (_background_last, _shadow_pass_of_casters)
        self._nodes["sea"] = self._scene.add(mesh)

    def close(self) -> None:
        """Forget this scene (the process's GL context lives until the process exits)."""
        self._scene = None
        self._nodes.clear()


def srgb_to_linear(rgb: NDArray[np.float64]) -> NDArray[np.float64]:
    """sRGB-encoded colours in [0, 1] to linear ones (IEC 61966-2-1), as pyrender decodes its textures."""
    c = np.asarray(rgb, float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _solid_mesh(pr: Any, mesh: Any, material: Any, *, linear: bool) -> Any:
    """A pyrender mesh of a trimesh with face colours, flat-shaded (colours sRGB-decoded for ``pbr``)."""
    faces = np.asarray(mesh.faces)
    rgb = np.asarray(mesh.visual.face_colors, float)[:, :3] / 255.0
    rgb = srgb_to_linear(rgb) if linear else rgb
    colour = np.repeat(np.column_stack([rgb, np.ones(len(rgb))]), 3, axis=0).astype(np.float32)
    prim = pr.Primitive(positions=np.asarray(mesh.vertices)[faces].reshape(-1, 3).astype(np.float32),
                        normals=np.repeat(np.asarray(mesh.face_normals), 3, axis=0).astype(np.float32),
                        color_0=colour, material=material)
    return pr.Mesh([prim])


def shadow_frame_m(casters_deck_m: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Where the sun's shadow map is centred and how far it reaches, so every shadow is in it.

    The sun's camera is orthographic: a shadow lies on the light's ray through the point
    that casts it, in that point's cell of the map. So the map needs to hold the casters
    only, whatever the ship's attitude: a caster's distance from the centre bounds its
    offset in any projection.

    Parameters
    ----------
    casters_deck_m : (N, 3) array of float
        The vertices of everything that casts a shadow (deck plate, hull, superstructure),
        deck frame, metres.

    Returns
    -------
    centre_deck_m : (3,) array of float
        The middle of the casters' extent in the deck plane, deck frame, metres.
    half_m : float
        Half the side of the square the map covers, metres: the farthest caster's distance
        from the centre, plus 5 % and 1 m.
    """
    xy = casters_deck_m[:, :2]
    centre = np.array([*(xy.min(0) + xy.max(0)) / 2.0, 0.0])
    reach = float(np.max(np.linalg.norm(casters_deck_m - centre, axis=1)))
    return centre, 1.05 * reach + 1.0


def _deck_shadow_camera(self: Any, scene_scale: float) -> Any:
    """A directional light's shadow camera over the ship (:func:`shadow_frame_m`, 500 m deep).

    pyrender puts the camera ``scene_scale`` (the 4 km sea's diagonal) back from the scene's
    centre toward the sun (:func:`deckpose.render.gl_context._shadow_view_over_ship` moves it over
    the ship). Its own
    camera covers that scale (5.5 m a texel of its 2048-texel map) and 0.01 to 10 times it in
    depth (57 km). Its shaders' depth bias (1e-4 to 1e-3 of the depth range) then came to
    6-57 m, so nothing within 6 m of its occluder was shadowed: the hull cast no shadow on
    the sea 6 m below the deck. This one frames the square :func:`shadow_frame_m` gives (90 m
    for the default ship, 4.4 cm a texel) and 250 m either side of the centre in depth: a
    bias of 5-50 cm.
    """
    import pyrender

    half_m = float(self.deckpose_shadow_half_m)
    return pyrender.OrthographicCamera(xmag=half_m, ymag=half_m, znear=max(scene_scale - 250.0, 0.01 * scene_scale),
                                       zfar=scene_scale + 250.0)


def radiance_scale(lighting: Lighting, shading: Shading) -> NDArray[np.float32]:
    """Per-channel factor from raster value / 255 to scene radiance (white = 1)."""
    light = PRESETS[lighting]
    if shading is Shading.PBR:
        return np.full(3, 1.0 / 255.0, np.float32)
    return (np.array(light.tint) * light.level / 255.0).astype(np.float32)
