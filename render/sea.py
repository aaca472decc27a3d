"""A deterministic animated sea: a few directional sine waves displacing a grid mesh.

The surface height at world ``(x, y)`` (metres, about the calm waterline ``z = -freeboard``)
and time ``t`` (seconds) is

    eta(x, y, t) = sum_i A_i sin(k_i . (x, y) - omega_i t + phi_i),    omega_i = sqrt(g |k_i|)

(deep-water dispersion, ``g`` = 9.81 m/s^2). ``n`` = ``scene.sea.waves`` components have
wavelengths spread over an octave either side of ``wavelength_m``, directions within
+-35 degrees of ``direction_deg`` and phases drawn once from ``scene.sea.seed``; they share
the energy equally, ``A_i = H_s / sqrt(8 n)``, so the significant height
``H_s = 4 sqrt(sum A_i^2 / 2)`` is ``height_m``. A frame's sea is a function of ``t_s``
alone, the same in every worker and every run.

Shading: the normals add short ripples (wavelengths 2-6 m, slopes only, no height) that
make the sun glitter in ``pbr`` shading; each vertex's colour is the water's, plus the
sky reflected with Schlick's Fresnel factor (``F0`` = 0.02, water's normal reflectance),
plus, in ``flat`` shading (no lights), a Lambert term toward the sun that shows the
waves' relief.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from deckpose.render.scene_config import SeaSpec
from numpy.typing import NDArray

__all__ = ["GRAVITY_M_PER_S2", "SEA_STREAM", "Waves", "sea_colour", "sea_grid_m", "sea_grid_surface",
           "sea_height_m", "sea_normals", "sea_waves"]

GRAVITY_M_PER_S2 = 9.81
#: Stream index of the sea's draws in ``SeedSequence([scene.sea.seed, stream])``.
SEA_STREAM = 5
#: Water's normal-incidence reflectance (refractive index 1.33: ((n - 1) / (n + 1))^2).
WATER_F0 = 0.02
#: Water colour (linear RGB, white = 1), as the flat sea texture's mean.
WATER_RGB = (0.05, 0.16, 0.24)
#: Ripples in the normals: count, wavelengths (m) and slope amplitude (radians).
_N_RIPPLES, _RIPPLE_LAMBDA_M, _RIPPLE_SLOPE = 6, (2.0, 6.0), 0.06


@dataclass(frozen=True)
class Waves:
    """Sine-wave components (``n`` of them).

    Attributes
    ----------
    amplitude_m : (n,) array of float
    k_per_m : (n, 2) array of float
        Wave vectors (radians per metre), world ``(x, y)``.
    omega_rad_per_s : (n,) array of float
    phase_rad : (n,) array of float
    """

    amplitude_m: NDArray[np.float64]
    k_per_m: NDArray[np.float64]
    omega_rad_per_s: NDArray[np.float64]
    phase_rad: NDArray[np.float64]

    def __post_init__(self) -> None:
        n = np.shape(self.amplitude_m)
        for name, shape in (("amplitude_m", n), ("k_per_m", (*n, 2)), ("omega_rad_per_s", n),
                            ("phase_rad", n)):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.shape != shape:
                raise ValueError(f"Waves.{name}: expected shape {shape}, got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)


def _components(rng: np.random.Generator, n: int, lambda_m: NDArray[np.float64], amplitude_m: NDArray[np.float64],
                direction_rad: float, spread_rad: float) -> Waves:
    heading = direction_rad + rng.uniform(-spread_rad, spread_rad, n)
    k = 2.0 * math.pi / lambda_m
    return Waves(amplitude_m, np.column_stack([k * np.cos(heading), k * np.sin(heading)]),
                 np.sqrt(GRAVITY_M_PER_S2 * k), rng.uniform(0.0, 2.0 * math.pi, n))


def sea_waves(spec: SeaSpec) -> tuple[Waves, Waves]:
    """The sea's height components and its slope-only ripples, drawn from ``spec.seed``.

    Returns
    -------
    waves, ripples : Waves
        ``ripples`` amplitudes are chosen so each ripple's slope amplitude ``A k`` is
        :data:`_RIPPLE_SLOPE`; they enter :func:`sea_normals` only.
    """
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, SEA_STREAM]))
    n = spec.waves
    lam = spec.wavelength_m * 2.0 ** np.linspace(-1.0, 1.0, n) if n > 1 else np.full(n, spec.wavelength_m)
    amp = np.full(n, spec.height_m / math.sqrt(8.0 * max(n, 1)))
    direction = math.radians(spec.direction_deg)
    waves = _components(rng, n, lam, amp, direction, math.radians(35.0))
    r_lam = np.geomspace(*_RIPPLE_LAMBDA_M, _N_RIPPLES)
    ripples = _components(rng, _N_RIPPLES, r_lam, _RIPPLE_SLOPE * r_lam / (2.0 * math.pi), direction, math.pi)
    return waves, ripples


def _phase(waves: Waves, xy_m: NDArray[np.float64], t_s: float) -> NDArray[np.float64]:
    return xy_m @ waves.k_per_m.T - waves.omega_rad_per_s * t_s + waves.phase_rad  # (M, n)


def sea_height_m(waves: Waves, xy_m: NDArray[np.float64], t_s: float) -> NDArray[np.float64]:
    """Surface height ``eta`` at world points, (M,) metres above the calm waterline.

    Parameters
    ----------
    waves : Waves
    xy_m : (M, 2) array of float
        World ``(x, y)``, metres.
    t_s : float
        Time, seconds.
    """
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    return np.sin(_phase(waves, xy, t_s)) @ waves.amplitude_m


def sea_normals(waves: Waves, ripples: Waves, xy_m: NDArray[np.float64], t_s: float) -> NDArray[np.float64]:
    """Unit surface normals, (M, 3): ``(-d eta/dx, -d eta/dy, 1)`` normalised, ripples' slopes added."""
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    grad = np.zeros((xy.shape[0], 2))
    for w in (waves, ripples):
        grad += (np.cos(_phase(w, xy, t_s)) * w.amplitude_m) @ w.k_per_m
    n = np.column_stack([-grad, np.ones(len(xy))])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def sea_grid_surface(waves: Waves, ripples: Waves, grid_m: NDArray[np.float64], t_s: float
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Heights and unit normals on the square grid ``grid_m x grid_m`` (x index first), fast.

    The same values as :func:`sea_height_m` and :func:`sea_normals` at the grid's points, by
    the angle-sum identity ``sin(a + b) = sin a cos b + cos a sin b`` with ``a = k_x x`` per row
    and ``b = k_y y - omega t + phi`` per column: two outer products per wave instead of a sine
    per vertex (27 ms for a 275 x 275 grid against 0.43 s, measured at load 8 on 2 cores).

    Returns
    -------
    height_m : (n * n,) array of float
    normals : (n * n, 3) array of float
    """
    g = np.asarray(grid_m, float)
    n = len(g)
    eta = np.zeros((n, n))
    gx, gy = np.zeros((n, n)), np.zeros((n, n))
    for w, heights in ((waves, True), (ripples, False)):
        for A, (kx, ky), om, ph in zip(w.amplitude_m, w.k_per_m, w.omega_rad_per_s, w.phase_rad, strict=True):
            a, b = kx * g, ky * g - om * t_s + ph
            sa, ca, sb, cb = np.sin(a), np.cos(a), np.sin(b), np.cos(b)
            cos_ab = np.outer(ca, cb) - np.outer(sa, sb)  # cos(a + b)
            if heights:
                eta += A * (np.outer(sa, cb) + np.outer(ca, sb))
            gx += A * kx * cos_ab
            gy += A * ky * cos_ab
    nrm = np.stack([-gx.ravel(), -gy.ravel(), np.ones(n * n)], axis=1)
    return eta.ravel(), nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def sea_grid_m(half_size_m: float, inner_half_m: float = 100.0, step_m: float = 2.0,
               growth: float = 1.15) -> NDArray[np.float64]:
    """Grid line positions along one axis, metres: ``step_m`` apart within ``+-inner_half_m``,
    then growing by ``growth`` per step out to ``+-half_size_m`` (fine where the camera looks)."""
    inner = np.arange(-inner_half_m, inner_half_m + 0.5 * step_m, step_m)
    outer = []
    x, d = inner_half_m, step_m
    while x < half_size_m:
        d *= growth
        x = min(half_size_m, x + d)
        outer.append(x)
    o = np.asarray(outer)
    return np.concatenate([-o[::-1], inner, o])


def sea_colour(normals: NDArray[np.float64], to_camera: NDArray[np.float64], sky_rgb: NDArray[np.float64],
               sun_dir: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """Vertex colours (M, 3) in [0, 1]: water, the sky by Schlick's Fresnel factor, and (``sun_dir``
    given: flat shading) a Lambert term ``0.6 + 0.8 max(0, n . s)`` on the water toward the sun.

    Parameters
    ----------
    normals, to_camera : (M, 3) arrays of float
        Unit normals and unit vectors from each vertex to the camera.
    sky_rgb : (3,) array of float
        Sky colour in the raster's units.
    sun_dir : (3,) array of float or None
        Unit vector toward the sun.
    """
    cos_v = np.clip(np.einsum("ij,ij->i", normals, to_camera), 0.0, 1.0)
    fresnel = WATER_F0 + (1.0 - WATER_F0) * (1.0 - cos_v) ** 5
    water = np.broadcast_to(np.asarray(WATER_RGB), normals.shape)
    if sun_dir is not None:
        water = water * (0.6 + 0.8 * np.clip(normals @ sun_dir, 0.0, None))[:, None]
    return np.clip((1.0 - fresnel)[:, None] * water + fresnel[:, None] * np.asarray(sky_rgb), 0.0, 1.0)
