"""Tile textures: the spread of an image on a spot's scale, tile by tile.

The significance search (:mod:`deckpose.detect.significance`) judges a candidate spot
against the noise *and* the texture of its surroundings: a sea or deck texture that makes
spot-like bumps raises the threshold where it is. This module measures that texture:
differences of pixels a ring's radius apart, in :data:`TEXTURE_TILE_PX` tiles
(:func:`texture_noise`), with the tiles of flat steps (a low-noise 8-bit night sea, one DN
per channel between flat patches) told apart (:func:`flat_step_tiles`), and each tile and
step computed once per image (:class:`TileTextures`).
"""

from __future__ import annotations

import math

import numpy as np
from deckpose.detect.background import MAD_TO_SIGMA, clipped_std_rows, row_median

__all__ = ["TEXTURE_TILE_PX", "TileTextures", "flat_step_tiles", "mad_spread", "pair_differences", "step_spread",
           "texture_noise", "tiles_of"]

#: Tile side of :func:`texture_noise`, coarse pixels.
TEXTURE_TILE_PX = 64


def tiles_of(ys: np.ndarray, xs: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The :data:`TEXTURE_TILE_PX` tiles holding some points, in row-major order.

    Parameters
    ----------
    ys, xs : (m,) arrays of int
        Rows and columns of the points, coarse pixels (non-negative).
    w : int
        Width of the image, coarse pixels.

    Returns
    -------
    tiles : (n, 2) array of int
        Tile row and column of each tile holding a point, each once.
    of : (m,) array of int
        Each point's tile, an index into ``tiles``.
    """
    n_cols = -(-w // TEXTURE_TILE_PX)
    flat = (ys // TEXTURE_TILE_PX) * n_cols + xs // TEXTURE_TILE_PX
    # np.unique(flat, return_inverse=True) by a count per tile (the tiles are few; a sort of
    # thousands of peaks' keys cost 7x more)
    keys = np.flatnonzero(np.bincount(flat))
    lut = np.zeros(keys[-1] + 1 if keys.size else 0, np.intp)
    lut[keys] = np.arange(keys.size)
    return np.column_stack([keys // n_cols, keys % n_cols]), lut[flat]


def texture_noise(G: np.ndarray, step_px: int, tiles: np.ndarray,
                  flat_steps: np.ndarray | None = None) -> np.ndarray:
    """Spread of a smoothed coarse image on a spot's scale in some tiles, (n,).

    Differences of pixels ``step_px`` apart (a ring's radius) along rows cancel
    smooth light and leave the noise and any texture at that scale:
    ``1.4826 MAD / sqrt(2)`` over every 4th row and column of each
    :data:`TEXTURE_TILE_PX` tile. A sea or deck texture that makes spot-like bumps
    raises the threshold where it is; an edge crossing a tile touches few of its
    samples.

    In a tile of flat steps (``flat_steps``, :func:`flat_step_tiles`) the MAD misreads
    the texture: most differences there are exactly 0 and the rest are steps of many
    noise sigmas, so the median of their sizes is far below their spread. There the
    spread is the larger of that and the differences' standard deviation clipped at
    4 sigma from the plain standard deviation (:func:`clipped_std_rows`, five passes: the
    iteration of astropy's ``sigma_clip``), which keeps the steps and drops a spot's few
    samples.

    Parameters
    ----------
    G : (h, w) array of float
    step_px : int
    tiles : (n, 2) array of int
        Tile rows and columns (``v // T``, ``u // T``).
    flat_steps : (n,) array of bool, optional
        Which tiles hold a texture of flat steps (none when not given).
    """
    d = pair_differences(G, step_px, tiles)
    return step_spread(d, mad_spread(d), flat_steps)


def pair_differences(G: np.ndarray, step_px: int, tiles: np.ndarray) -> np.ndarray:
    """Differences of pixels ``step_px`` apart along rows, every 4th row and column of each tile, (n, m)."""
    h, w = G.shape
    T, st = TEXTURE_TILE_PX, 4
    offs = np.arange(0, T, st)
    rows = np.minimum(tiles[:, 0:1] * T + offs[None], h - 1)  # (n, T/st)
    cols = np.minimum(tiles[:, 1:2] * T + offs[None], w - 1 - step_px)
    cols = np.maximum(cols, 0)
    # flat indices into G: one take per side (a 2-D fancy index costs 3x more)
    n = tiles.shape[0]
    row0 = rows[:, :, None] * w
    at = (row0 + cols[:, None, :]).reshape(n, -1)
    right = (row0 + np.minimum(cols + step_px, w - 1)[:, None, :]).reshape(n, -1)
    flat = G.ravel()
    return flat.take(right) - flat.take(at)


def mad_spread(d: np.ndarray) -> np.ndarray:
    """``1.4826 MAD / sqrt(2)`` of each row of pixel-pair differences, (n,)."""
    med = row_median(d)
    return MAD_TO_SIGMA * row_median(np.abs(d - med[:, None])) / math.sqrt(2.0)


def step_spread(d: np.ndarray, spread: np.ndarray, flat_steps: np.ndarray | None) -> np.ndarray:
    """``spread``, where ``flat_steps`` the larger of it and the clipped standard deviation of ``d``."""
    if flat_steps is None or not flat_steps.any():
        return spread
    ds = d[flat_steps]
    out = spread.copy()
    out[flat_steps] = np.maximum(spread[flat_steps], clipped_std_rows(ds, ds.std(axis=1), passes=5) / math.sqrt(2.0))
    return out


def flat_step_tiles(spread_2px: np.ndarray, noise: float) -> np.ndarray:
    """Which tiles hold a texture of flat steps, (n,) bool.

    A tile whose :func:`texture_noise` at a 2-px step is below half the image's pixel
    noise ``noise`` (``sigma_G``): more than half of its differences are equal, which
    noise never gives (the MAD of 256 differences of noise is within 8 % of it, one
    sigma). A night sea or deck on a low-noise 8-bit sensor is such a texture: steps of
    one DN per channel, each many noise sigmas, between flat patches.
    """
    return spread_2px < 0.5 * noise


class TileTextures:
    """:func:`texture_noise` of an image per step and :data:`TEXTURE_TILE_PX` tile, each once.

    With ``noise`` (the image's ``sigma_G``), tiles of flat steps (:func:`flat_step_tiles`,
    from their 2-px texture) get the step texture's spread at every step.
    """

    def __init__(self, G: np.ndarray, noise: float = 0.0) -> None:
        self.G = G
        self.noise = noise
        self.n_cols = -(-G.shape[1] // TEXTURE_TILE_PX)
        self.n_tiles = -(-G.shape[0] // TEXTURE_TILE_PX) * self.n_cols
        self.done: dict[int, np.ndarray] = {}
        self.plain_2px = np.full(self.n_tiles, np.nan)  # the MAD rule at 2 px, for the flags

    def tile_of(self, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        """Flat index (row-major) of the tile of each point ``(ys, xs)``, coarse px; (n,) int."""
        return (ys // TEXTURE_TILE_PX) * self.n_cols + xs // TEXTURE_TILE_PX

    def _rc(self, tiles: np.ndarray) -> np.ndarray:
        return np.column_stack([tiles // self.n_cols, tiles % self.n_cols])

    def _flat_steps(self, tiles: np.ndarray) -> np.ndarray | None:
        if not self.noise > 0:
            return None
        todo = tiles[np.isnan(self.plain_2px[tiles])]
        if todo.size:
            self.plain_2px[todo] = mad_spread(pair_differences(self.G, 2, self._rc(todo)))
        return flat_step_tiles(self.plain_2px[tiles], self.noise)

    def of_tiles(self, step_px: int, tiles: np.ndarray) -> np.ndarray:
        """Texture noise at ``step_px`` of every tile, (n_tiles,): those in ``tiles`` (flat
        indices) computed, the others NaN unless asked for before."""
        vals = self.done.setdefault(step_px, np.full(self.n_tiles, np.nan))
        todo = np.unique(tiles[np.isnan(vals[tiles])])
        if todo.size:
            d = pair_differences(self.G, step_px, self._rc(todo))
            plain = mad_spread(d)
            if step_px == 2:  # the flags' own spread: not computed a second time
                self.plain_2px[todo] = plain
            vals[todo] = step_spread(d, plain, self._flat_steps(todo))
        return vals

    def at(self, step_px: int, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        """Texture noise of the tile of each point ``(ys, xs)`` (coarse px) at ``step_px``, (n,)."""
        tile = self.tile_of(ys, xs)
        return self.of_tiles(step_px, tile)[tile]
