"""The process's one pyrender OffscreenRenderer, and what this project changes on it.

One GL context per process: pyrender's EGL platform terminates the shared display when
any renderer is deleted, so two contexts in one process break each other. Every scene
(:class:`deckpose.render.scene.DeckRenderer`, tests' own) draws through :func:`offscreen`.
Its pyrender ``Renderer`` gets these changes (:func:`_patch_renderer`): the read-back
straight into the frame, the multisample count per scene, the sea drawn last and left
out of the shadow pass, one shadow pass a frame, and the sun's shadow camera over the ship.
"""

from __future__ import annotations

import atexit
import threading
import types
from typing import Any

import cv2
import numpy as np

_OFFSCREEN: list[Any] = []
#: The thread that made the GL context (it is current there).
_OFFSCREEN_THREAD: list[int] = []


def offscreen(pr: Any, width: int, height: int, samples: int = 4) -> Any:
    """The process's single OffscreenRenderer, resized to ``width x height``, ``samples`` MSAA.

    One GL context per process: pyrender's EGL platform terminates the shared
    display when any renderer is deleted, so two contexts in one process break each
    other. Scenes share the context; the framebuffer is re-made when the size or the
    sample count changes.
    """
    if not _OFFSCREEN:
        r = pr.OffscreenRenderer(width, height)
        _patch_renderer(r._renderer)
        _OFFSCREEN.append(r)
        _OFFSCREEN_THREAD[:] = [threading.get_ident()]
        atexit.register(_delete_offscreen)
    r = _OFFSCREEN[0]
    r.viewport_width = width
    r.viewport_height = height
    if not r._platform.supports_framebuffers() and (
            (r._platform.viewport_width, r._platform.viewport_height) != (width, height)):
        # OSMesa draws into the context's own buffer: pyrender re-makes the context and its
        # Renderer at each new size, inside render(), unpatched. Done here, the new one is patched.
        sun_programs = getattr(r._renderer, "deckpose_sun_programs", None)
        if sun_programs is not None:  # freed in their own context, not later in the new one
            r._platform.make_current()
            sun_programs.clear()
        r.delete()
        r._create()
        _patch_renderer(r._renderer)
    r._renderer.deckpose_samples = samples
    return r


def _patch_renderer(gl: Any) -> None:
    """Put this module's changes on a pyrender ``Renderer`` (see each function)."""
    gl._read_main_framebuffer = types.MethodType(_read_colour_only, gl)
    gl._configure_main_framebuffer = types.MethodType(_configure_framebuffer, gl)
    gl._shadow_mapping_pass = types.MethodType(_shadow_pass_of_casters, gl)
    gl._sorted_mesh_nodes = types.MethodType(_background_last, gl)
    gl._get_light_cam_matrices = types.MethodType(_shadow_view_over_ship, gl)


def _configure_framebuffer(self: Any) -> None:
    """pyrender's ``Renderer._configure_main_framebuffer`` with ``self.deckpose_samples`` samples.

    pyrender draws into a 4-sample buffer and resolves it into a plain one; the count is
    fixed there. Here it is the scene's ``antialias_samples`` (0: a single-sample draw
    buffer, resolved by a plain copy). The buffers are re-made when the size or the count
    changes.
    """
    from OpenGL import GL

    samples = int(getattr(self, "deckpose_samples", 4))
    w, h = self.viewport_width, self.viewport_height
    if self._main_fb is not None and (self._main_fb_dims != (w, h)
                                      or getattr(self, "_deckpose_fb_samples", 4) != samples):
        self._delete_main_framebuffer()
    if self._main_fb is not None:
        return
    self._main_cb, self._main_db = GL.glGenRenderbuffers(2)
    GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb)
    GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_RGBA, w, h)
    GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db)
    GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH_COMPONENT24, w, h)
    self._main_fb = GL.glGenFramebuffers(1)
    GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
    GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, self._main_cb)
    GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, self._main_db)
    self._main_cb_ms, self._main_db_ms = GL.glGenRenderbuffers(2)
    GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb_ms)
    GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, GL.GL_RGBA, w, h)
    GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db_ms)
    GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, GL.GL_DEPTH_COMPONENT24, w, h)
    self._main_fb_ms = GL.glGenFramebuffers(1)
    GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb_ms)
    GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER,
                                 self._main_cb_ms)
    GL.glFramebufferRenderbuffer(GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER,
                                 self._main_db_ms)
    self._main_fb_dims = (w, h)
    self._deckpose_fb_samples = samples


def _background_last(self: Any, scene: Any) -> list[Any]:
    """pyrender's ``Renderer._sorted_mesh_nodes`` with the meshes marked ``deckpose_background`` last.

    pyrender draws solid meshes farthest origin first, which put the sea (its origin 6 m
    below the deck's) under the ship first: every pixel of the ship was shaded twice. Drawn
    last, the sea's hidden fragments fail the depth test before they are shaded. The depth
    test picks the same surface in either order, so the frame is the same.
    """
    solid: list[Any] = []
    back: list[Any] = []
    clear: list[Any] = []  # transparent ones stay after all solids
    for n in type(self)._sorted_mesh_nodes(self, scene):
        group = clear if n.mesh.is_transparent else back if getattr(n.mesh, "deckpose_background", False) else solid
        group.append(n)
    return solid + back + clear


def _shadow_pass_of_casters(self: Any, scene: Any, light_node: Any, flags: int) -> None:
    """pyrender's ``Renderer._shadow_mapping_pass`` without the meshes marked ``deckpose_background``,
    once a frame.

    The sea fills the whole shadow map, so drawing its depth was most of the pass's cost,
    and it shades nothing: its waves are far too gentle to shadow each other under a sun
    54 degrees up (slopes of a few degrees). Left out, the map holds the ship and the deck,
    and a point of the sea outside their shadow reads the cleared (farthest) depth: lit.
    pyrender draws the map for every draw call; a large frame is drawn in tiles, all with
    the same scene and sun, so :meth:`deckpose.render.scene.DeckRenderer.render` sets ``deckpose_shadow_map_drawn``
    after the first tile and the map is kept.
    """
    if getattr(self, "deckpose_shadow_map_drawn", False):
        return  # drawn for this frame's first tile: the same scene, light and map
    hidden = [m for m in scene.meshes if getattr(m, "deckpose_background", False) and m.is_visible]
    for m in hidden:
        m.is_visible = False
    try:
        type(self)._shadow_mapping_pass(self, scene, light_node, flags)
    finally:
        for m in hidden:
            m.is_visible = True


def _read_colour_only(self: Any, scene: Any, flags: int) -> tuple[np.ndarray, None]:
    """pyrender's framebuffer read without the depth buffer (we never use it).

    Replaces ``Renderer._read_main_framebuffer`` on our one renderer: resolves the
    multisampled colour buffer and reads RGB bytes only, skipping pyrender's
    float depth read-back and linearisation (a third of the time of a 64 MP frame).

    Where ``self.deckpose_read_into`` is a C-contiguous ``(h, width, 3)`` uint8 array (rows
    of the frame being drawn, ``h`` at most the framebuffer's height), the top ``h`` image
    rows are read straight into it and flipped there (OpenGL's rows run bottom-up): no
    frame-sized array is allocated and none is copied. Otherwise a new array is returned.
    """
    from OpenGL import GL

    width, height = self._main_fb_dims[0], self._main_fb_dims[1]
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
    # a single-sample draw buffer needs no resolve: it is read where it was drawn (the copy
    # into the plain buffer cost 0.5-0.9 s of CPU per 64 MP frame on llvmpipe)
    if getattr(self, "_deckpose_fb_samples", 4) != 0:
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
        GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_LINEAR)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    target = getattr(self, "deckpose_read_into", None)
    if target is not None:
        h = target.shape[0]
        if target.shape != (h, width, 3) or target.dtype != np.uint8 or not target.flags.c_contiguous \
                or h > height:
            raise ValueError(f"read-back target {target.shape} {target.dtype} does not fit a {width}x{height} "
                             "RGB framebuffer")
        # the image's top h rows are the framebuffer's last h rows (bottom-up)
        GL.glReadPixels(0, height - h, width, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE, target)
        cv2.flip(target, 0, dst=target)  # in place: rows swapped pairwise
        return target, None
    # bytes, or an array: PyOpenGL has no types, and pyright's guess from its source adds int
    buf: Any = GL.glReadPixels(0, 0, width, height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
    colour = np.frombuffer(buf, dtype=np.uint8).reshape((height, width, 3))
    return colour[::-1], None


def _delete_offscreen() -> None:
    """Release the GL context at exit, from the thread it is current in.

    A Dask worker renders in a task thread, while ``atexit`` runs in the main one: EGL
    refuses to make the context current there (EGL_BAD_ACCESS, printed as an ignored
    exception at every worker's exit). The process is ending, so the context is then
    left to the driver's teardown.
    """
    while _OFFSCREEN:
        r = _OFFSCREEN.pop()
        if _OFFSCREEN_THREAD and _OFFSCREEN_THREAD[0] != threading.get_ident():
            continue
        r.delete()


def _shadow_view_over_ship(self: Any, scene: Any, light_node: Any, flags: int) -> tuple[Any, Any]:
    """pyrender's ``Renderer._get_light_cam_matrices``, a directional light's camera over the ship.

    pyrender aims it at the centre of the scene's bounding box, which the drifting 4 km sea
    moves tens of metres; :meth:`deckpose.render.scene.DeckRenderer.render` sets ``deckpose_shadow_centre`` (world,
    metres: :func:`deckpose.render.scene.shadow_frame_m`'s centre under the ship's pose) for the frame.
    """
    V, P = type(self)._get_light_cam_matrices(self, scene, light_node, flags)
    centre = getattr(self, "deckpose_shadow_centre", None)
    if centre is None or not hasattr(light_node.light, "deckpose_shadow_half_m"):
        return V, P
    pose = scene.get_pose(light_node).copy()
    pose[:3, 3] = np.asarray(centre) + pose[:3, 2] * scene.scale  # toward the sun: the light's +z
    return np.linalg.inv(pose), P
