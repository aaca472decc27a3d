"""The rasteriser agrees with CameraModel.K (OpenGL half-pixel and row flip handled), and tiling is seamless."""

from __future__ import annotations

import numpy as np
import pytest
from deckpose.render import scene as scene_mod
from deckpose.render.config import Lighting

from deckpose.camera import CameraModel
from deckpose.pose import CameraPose, ShipPose

from .conftest import tiny_config


def _white_square_image(renderer, camera: CameraModel, cam_pose: CameraPose, centre_xy: tuple[float, float],
                        angle_rad: float, side_m: float) -> np.ndarray:
    import pyrender

    c, s = np.cos(angle_rad), np.sin(angle_rad)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * side_m / 2 @ np.array([[c, s], [-s, c]])
    pos = np.c_[corners + centre_xy, np.zeros(4)].astype(np.float32)
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0])
    prim = pyrender.Primitive(positions=pos, indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32), material=mat)
    sc = pyrender.Scene(bg_color=[0, 0, 0, 1])
    sc.add(pyrender.Mesh([prim]))
    sc.add(pyrender.IntrinsicsCamera(*scene_mod.gl_intrinsics(camera, 0, camera.height_px), znear=0.1, zfar=100),
           pose=scene_mod.gl_camera_pose(cam_pose))
    r = renderer.offscreen(camera.width_px, camera.height_px)
    color, _ = r.render(sc, flags=pyrender.RenderFlags.FLAT | pyrender.RenderFlags.SKIP_CULL_FACES)
    return color[..., 0].astype(float)


@pytest.mark.parametrize("centre_xy", [(3.1, -2.7), (-4.4, 5.3)])
def test_raster_centroid_matches_K(egl_renderer_factory, centre_xy: tuple[float, float]) -> None:
    """A white square on the ground, nadir camera (affine view): its image centroid = K-projected centre.

    An off-by-half-pixel convention error would show as 0.5 px; 4x MSAA edge coverage
    leaves a few hundredths.
    """
    renderer = egl_renderer_factory(tiny_config())
    cam = CameraModel(400, 300, [[480.0, 0, 203.7], [0, 470.0, 146.2], [0, 0, 1]])
    pose = CameraPose.nadir(20.0)
    img = _white_square_image(renderer, cam, pose, centre_xy, 0.3, 3.0)
    vv, uu = np.mgrid[0:300, 0:400]
    got = np.array([(img * uu).sum(), (img * vv).sum()]) / img.sum()
    want = cam.project((pose.T_cam_from_world @ np.r_[centre_xy, 0.0, 1.0])[None, :3])[0]
    np.testing.assert_allclose(got, want, atol=0.05)


def test_tiled_render_equals_single_pass(egl_renderer_factory, monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = tiny_config()
    r = egl_renderer_factory(cfg)
    cam = CameraModel(320, 240, [[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    args = (cam, CameraPose.nadir(30.0), ShipPose(0.05, -0.04, 0.3), 1.0, Lighting.DAY)
    whole = r.render(*args).astype(int)
    monkeypatch.setattr(scene_mod, "MAX_TILE_PX", 320 * 70)  # 4 tiles of 60 rows
    tiled = r.render(*args).astype(int)
    diff = np.abs(whole - tiled)
    assert diff.mean() < 0.05 and diff.max() <= 3


def _triangle_scene():
    """A 200 x 150 camera and a pyrender scene of an asymmetric flat triangle in its view."""
    import pyrender

    cam = CameraModel(200, 150, [[240.0, 0, 101.3], [0, 235.0, 73.1], [0, 0, 1]])
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[0.9, 0.5, 0.2, 1.0])
    pos = np.array([[-2, -1, 0], [3, -2, 0], [1, 3, 0]], np.float32)  # an asymmetric triangle
    sc = pyrender.Scene(bg_color=[0.1, 0.2, 0.3, 1])
    sc.add(pyrender.Mesh([pyrender.Primitive(positions=pos, indices=np.array([[0, 1, 2]], np.uint32),
                                             material=mat)]))
    sc.add(pyrender.IntrinsicsCamera(*scene_mod.gl_intrinsics(cam, 0, cam.height_px), znear=0.1, zfar=100),
           pose=scene_mod.gl_camera_pose(CameraPose.nadir(10.0)))
    return cam, sc


def test_read_back_into_the_frame_equals_pyrenders_read(egl_renderer_factory) -> None:
    """Read back straight into rows of a preallocated frame (flipped in place) gives the top rows
    of the image the plain read returns, byte for byte; a tile shorter than the framebuffer too."""
    import pyrender

    renderer = egl_renderer_factory(tiny_config())
    cam, sc = _triangle_scene()
    r = renderer.offscreen(cam.width_px, cam.height_px)
    flags = pyrender.RenderFlags.FLAT | pyrender.RenderFlags.SKIP_CULL_FACES
    plain, _ = r.render(sc, flags=flags)
    assert plain.std() > 0  # the triangle is in view
    frame = np.zeros((400, cam.width_px, 3), np.uint8)
    for rows in (frame[7:7 + cam.height_px], frame[200:200 + 111]):  # a whole tile, a short last tile
        r._renderer.deckpose_read_into = rows
        try:
            got, _ = r.render(sc, flags=flags)
        finally:
            r._renderer.deckpose_read_into = None
        assert got is rows
        np.testing.assert_array_equal(rows, plain[: rows.shape[0]])
    assert not frame[:7].any() and not frame[7 + cam.height_px:200].any()  # nothing outside the rows


def test_a_single_sample_buffer_is_read_without_a_resolve_and_equals_the_resolved_copy(
        egl_renderer_factory) -> None:
    """With ``antialias_samples: 0`` the draw buffer is read where it was drawn; a resolve into the
    plain buffer (what pyrender does) and a read of that gives the same bytes."""
    import pyrender
    from OpenGL import GL

    renderer = egl_renderer_factory(tiny_config(scene={"shading": "flat", "texture_px": 256,
                                                       "antialias_samples": 0}))
    cam, sc = _triangle_scene()
    r = renderer.offscreen(cam.width_px, cam.height_px)
    got, _ = r.render(sc, flags=pyrender.RenderFlags.FLAT | pyrender.RenderFlags.SKIP_CULL_FACES)
    assert r._renderer._deckpose_fb_samples == 0 and got.std() > 0
    w, h = r._renderer._main_fb_dims
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, r._renderer._main_fb_ms)
    GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, r._renderer._main_fb)
    GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_COLOR_BUFFER_BIT, GL.GL_LINEAR)
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, r._renderer._main_fb)
    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    buf = GL.glReadPixels(0, 0, w, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
    resolved = np.frombuffer(buf, np.uint8).reshape(h, w, 3)[::-1]
    np.testing.assert_array_equal(got, resolved)


def test_lighting_presets_order_brightness(egl_renderer_factory) -> None:
    """Night is darker than dusk, dusk darker than day (deck and sea radiance)."""
    cfg = tiny_config()
    r = egl_renderer_factory(cfg)
    cam = CameraModel(160, 120, [[150.0, 0, 80], [0, 150.0, 60], [0, 0, 1]])
    mean = {}
    for light in Lighting:
        raw = r.render(cam, CameraPose.nadir(30.0), ShipPose(), 0.0, light)
        mean[light] = float((raw.astype(np.float32) * scene_mod.radiance_scale(light, cfg.scene.shading)).mean())
    assert mean[Lighting.NIGHT] < mean[Lighting.DUSK] < mean[Lighting.DAY]


def test_distortion_remap_moves_raster_to_the_distorted_projection(egl_renderer_factory) -> None:
    """A small white square rendered pinhole, then warped with cv2.remap: its centroid lands on
    CameraModel.project (distorted) of its centre, not on the pinhole position."""
    from deckpose.render.lens import distort, raster_camera

    renderer = egl_renderer_factory(tiny_config())
    K = [[300.0, 0, 201.3], [0, 300.0, 148.8], [0, 0, 1]]
    cam = CameraModel(400, 300, K, [-0.25, 0.08, 0.0, 0.0, 0.0])
    pinhole = raster_camera(cam)
    pose = CameraPose.nadir(20.0)
    centre = (-6.0, 7.5)  # far off-axis, where the distortion is several pixels
    img = _white_square_image(renderer, pinhole, pose, centre, 0.2, 0.6)
    rgb = np.repeat(np.clip(img, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    warped = distort(rgb, cam)[..., 0].astype(float)
    vv, uu = np.mgrid[0:300, 0:400]
    got = np.array([(warped * uu).sum(), (warped * vv).sum()]) / warped.sum()
    P = (pose.T_cam_from_world @ np.r_[centre, 0.0, 1.0])[None, :3]
    want, ideal = cam.project(P)[0], CameraModel(400, 300, K).project(P)[0]
    assert np.linalg.norm(want - ideal) > 3.0
    print(f"\nraster centroid after distortion: {np.linalg.norm(got - want):.3f} px from the projection")
    np.testing.assert_allclose(got, want, atol=0.1)


@pytest.mark.parametrize(("dist", "model"), [([-0.25, 0.08, 0.001, 0.0, 0.0], ""),
                                             ([-0.2, 0.05, 0.001, 0.0, 0.01, 0.04, -0.01, 0.003],
                                              "rational_polynomial"),
                                             ([0.02, -0.01, 0.003, -0.001], "equidistant")])
def test_distortion_maps_match_undistort(dist: list[float], model: str) -> None:
    """The remap table takes every distorted pixel to the raster pixel of CameraModel.undistort of
    it (1/32 px fixed point), and the raster holds every pixel's ray."""
    import cv2
    from deckpose.render.lens import distortion_maps, raster_camera

    cam = CameraModel(200, 150, [[150.0, 0, 99.5], [0, 150.0, 74.5], [0, 0, 1]], dist, distortion_model=model)
    pin = raster_camera(cam)
    assert not pin.has_distortion
    m1, m2 = distortion_maps(cam)
    mx, my = cv2.convertMaps(m1, m2, cv2.CV_32FC1)
    vv, uu = np.mgrid[0:150:7, 0:200:9]
    ray = (cam.undistort(np.c_[uu.ravel(), vv.ravel()]) - cam.K[:2, 2]) / [cam.fx, cam.fy]  # zero skew
    src = ray * [pin.fx, pin.fy] + pin.K[:2, 2]
    got = np.c_[mx[vv.ravel(), uu.ravel()], my[vv.ravel(), uu.ravel()]]
    np.testing.assert_allclose(got, src, atol=1 / 32 + 1e-3)
    assert mx.min() >= 0 and my.min() >= 0 and mx.max() <= pin.width_px - 1 and my.max() <= pin.height_px - 1


def test_raster_camera_grows_only_where_the_rays_need_it() -> None:
    """Pincushion: the camera's own K and size; barrel and fisheye: a larger canvas at the same
    focal length; a strong fisheye: the focal length lowered to keep the canvas at 4x the image."""
    from deckpose.render.lens import MAX_RASTER_AREA, raster_camera

    K = [[150.0, 0, 99.5], [0, 150.0, 74.5], [0, 0, 1]]
    pincushion = raster_camera(CameraModel(200, 150, K, [0.1, 0.0, 0.0, 0.0, 0.0]))
    assert (pincushion.width_px, pincushion.height_px) == (200, 150)
    np.testing.assert_array_equal(pincushion.K, K)
    barrel = raster_camera(CameraModel(200, 150, K, [-0.25, 0.08, 0.0, 0.0, 0.0]))
    assert barrel.width_px > 200 and barrel.height_px > 150 and barrel.fx == 150.0
    fisheye = CameraModel(200, 150, [[100.0, 0, 99.5], [0, 100.0, 74.5], [0, 0, 1]], [0.0] * 4,
                          distortion_model="equidistant")  # corner ray: 125 px / 100 px = 1.25 rad, 72 deg
    wide = raster_camera(fisheye)  # at f = 100 about 480 x 360 px (tan(1.25 rad) = 3.0), over 4x the image
    assert 50.0 < wide.fx < 100.0 and wide.width_px * wide.height_px <= MAX_RASTER_AREA * 200 * 150 * 1.05


@pytest.mark.parametrize("f_px", [20.0, 40.0])
def test_raster_camera_refuses_rays_beyond_the_limit(f_px: float) -> None:
    """A fisheye whose corners see 179 deg (f = 40 px) or 358 deg (f = 20 px) off the axis has no
    pinhole raster: one line naming the limit."""
    from deckpose.render.lens import MAX_RAY_ANGLE_DEG, raster_camera

    from deckpose.errors import ConfigError

    cam = CameraModel(200, 150, [[f_px, 0, 99.5], [0, f_px, 74.5], [0, 0, 1]], [0.0] * 4,
                      distortion_model="equidistant", name="wide")
    with pytest.raises(ConfigError, match=rf"camera wide: .*90 deg.*up to {MAX_RAY_ANGLE_DEG:g} deg") as err:
        raster_camera(cam)
    assert "\n" not in str(err.value)


def test_raster_camera_refuses_a_fisheye_past_80_degrees() -> None:
    """Corners at 85 deg: a pinhole could hold them (tan 85 deg = 11.4 focal lengths) but not usefully."""
    from deckpose.render.lens import raster_camera

    from deckpose.errors import ConfigError

    f = np.hypot(99.5, 74.5) / np.radians(85.0)  # the corner pixel's radius over its ray angle
    cam = CameraModel(200, 150, [[f, 0, 99.5], [0, f, 74.5], [0, 0, 1]], [0.0] * 4, distortion_model="equidistant")
    with pytest.raises(ConfigError, match=r"200x150 equidistant camera: its edge pixels see rays 85\.0 deg off"):
        raster_camera(cam)


def test_the_gl_context_is_released_only_from_the_thread_it_is_current_in(monkeypatch):
    # A Dask worker renders in a task thread and atexit runs in the main thread, where EGL
    # refuses the context (EGL_BAD_ACCESS printed at every worker's exit): leave it there.
    import threading

    deleted = []

    from deckpose.render import gl_context

    class FakeRenderer:
        def delete(self):
            deleted.append(threading.get_ident())

    monkeypatch.setattr(gl_context, "_OFFSCREEN", [FakeRenderer()])
    monkeypatch.setattr(gl_context, "_OFFSCREEN_THREAD", [threading.get_ident() + 1])
    gl_context._delete_offscreen()
    assert deleted == [] and gl_context._OFFSCREEN == []
    monkeypatch.setattr(gl_context, "_OFFSCREEN", [FakeRenderer()])
    monkeypatch.setattr(gl_context, "_OFFSCREEN_THREAD", [threading.get_ident()])
    gl_context._delete_offscreen()
    assert deleted == [threading.get_ident()]


@pytest.mark.parametrize("samples", [0, 4])
def test_antialias_samples_set_the_edge_coverage(egl_renderer_factory, samples: int) -> None:
    """``scene.antialias_samples``: with 0 an edge pixel is on or off; with 4 it takes the
    coverage steps k/4 in between. Either way the square's area (its summed intensity) is
    the K-projected area: 4.4 m at 20 m with f = 480 px is 105.6 px a side, and aliasing
    moves at most half a pixel along each of its four edges (4 x 105.6 x 0.5 px^2, 1.9 % of
    the area) - the bound used, with the mean error far smaller."""
    cfg = tiny_config(scene={"shading": "flat", "texture_px": 256, "antialias_samples": samples})
    renderer = egl_renderer_factory(cfg)
    cam = CameraModel(400, 300, [[480.0, 0, 200.0], [0, 480.0, 150.0], [0, 0, 1]])
    img = _white_square_image(renderer, cam, CameraPose.nadir(20.0), (0.37, -0.21), 0.3, 4.4)
    levels = np.unique(img)
    partial = levels[(levels > 0) & (levels < 255)]
    if samples == 0:
        assert partial.size == 0, partial
    else:
        # resolved coverage k/4 of 255 (FLAT colour, no sRGB curve), rounded to bytes
        assert set(partial.tolist()) == {64.0, 128.0, 191.0}
    area_px = img.sum() / 255.0
    want = (4.4 * 480.0 / 20.0) ** 2
    assert abs(area_px - want) < 4 * 105.6 * 0.5


def test_switching_antialias_samples_remakes_the_buffer(egl_renderer_factory) -> None:
    """Renderers of two sample counts share the process's one GL context: each draw uses its
    own count (the buffer is re-made when the count changes), so a draw repeats exactly."""
    cam = CameraModel(320, 240, [[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    args = (cam, CameraPose.nadir(30.0), ShipPose(0.05, -0.04, 0.3), 1.0, Lighting.DAY)
    r4 = egl_renderer_factory(tiny_config())
    r0 = egl_renderer_factory(tiny_config(scene={"shading": "flat", "texture_px": 256, "antialias_samples": 0}))
    a4 = r4.render(*args)
    a0 = r0.render(*args)
    b4 = r4.render(*args)
    assert np.array_equal(a4, b4) and not np.array_equal(a4, a0)
    # only edges differ (markings, the deck's rim): a small share of the pixels
    assert np.mean(np.any(a4 != a0, axis=2)) < 0.05


def test_texture_seed_draws_another_deck_of_the_same_statistics(egl_renderer_factory) -> None:
    """``scene.texture_seed``: another non-skid grain (uncorrelated with the default's), the same
    grey level and spread, and the renderer draws it (the painted ring's edge errors follow the grain,
    so a benchmark needs more than one)."""
    from deckpose.render.scene_config import DEFAULT_TEXTURE_SEED

    from deckpose.layout import DeckLayout

    layout = DeckLayout()
    a = scene_mod.deck_texture(layout, 14.0, 512, DEFAULT_TEXTURE_SEED)[..., 0].astype(float)
    b = scene_mod.deck_texture(layout, 14.0, 512, 7)[..., 0].astype(float)
    # the same markings; the grain only where both are plain deck (grey, within the base's +-4 sigma)
    plain = (np.abs(a - 107) < 60) & (np.abs(b - 107) < 60)
    assert plain.mean() > 0.5
    ga, gb = a[plain] - a[plain].mean(), b[plain] - b[plain].mean()
    # two independent draws of ~1.5e5 correlated pixels (the coarse grain spans 8 texels, so about
    # 2,000 independent cells): a correlation beyond 0.15 would be ~7 standard errors
    assert abs(float(np.corrcoef(ga, gb)[0, 1])) < 0.15
    assert a[plain].mean() == pytest.approx(b[plain].mean(), abs=3.0)  # level: 0.42 * 255 = 107 +- sampling
    assert ga.std() == pytest.approx(gb.std(), rel=0.15)
    # the renderer takes it from the config: the same view, another deck
    cam = CameraModel(320, 240, [[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])
    args = (cam, CameraPose.nadir(20.0), ShipPose(0.0, 0.0, 0.0), 1.0, Lighting.DAY)
    base = tiny_config()
    seeded = tiny_config(scene={**tiny_doc_scene(), "texture_seed": 7})
    assert seeded.scene.texture_seed == 7 and base.scene.texture_seed == DEFAULT_TEXTURE_SEED
    img_a = egl_renderer_factory(base).render(*args).astype(float)
    img_b = egl_renderer_factory(seeded).render(*args).astype(float)
    assert np.abs(img_a - img_b).mean() > 1.0


def tiny_doc_scene() -> dict:
    from .conftest import tiny_doc

    return dict(tiny_doc()["scene"])


@pytest.mark.parametrize("bad", [-1, "7", 1.5])
def test_texture_seed_must_be_a_non_negative_integer(bad: object) -> None:
    from deckpose.errors import ConfigError

    with pytest.raises(ConfigError, match="texture_seed"):
        tiny_config(scene={**tiny_doc_scene(), "texture_seed": bad})
