"""Beacon frames from a generator that shares no code with ``render/`` or ``detect/``.

The detectors must hold on frames the project did not render. This module makes
such frames from first principles, with its own projection, its own spot model
and its own noise and Cramér–Rao bound, so a shortcut shared with our renderer
or our analytic-spot generator (:mod:`deckpose.detect.synthetic`) cannot hide a
detector's fault:

* geometry: the 12 + 1 beacons of the standard deck (radius 10 m, bow at +x,
  ids counter-clockwise seen from above, centre beacon last) seen by a pinhole
  camera from a random height, tilt and yaw; projected here with ``K [R | t]``;
* spots: pixel-integrated (erf) circular Gaussians, sigma and flux per beacon,
  flux split over channels by the beacon's colour (white, or the red bow);
  uneven brightness (each beacon's flux times U(lo, hi)) and a dimmer bow;
* other lights (red and green sidelights, white floodlights, small glints)
  placed off the ring; missing ring beacons and a missing centre beacon;
* sensor: Poisson photon noise on signal + background, Gaussian read noise,
  gain to DN, rounding, full-scale clipping; 8-bit, 12-bit-in-16-bit or 16-bit;
  RGB or mono;
* truth: every beacon's exact centre and the per-axis centroid CRB of the
  channel-sum image (Fisher information of the pixel-integrated spot under
  Poisson + read noise + the rounding to the stored DN step, as Gaussian variances,
  the spot's other parameters known).

Only numpy and scipy are used. Everything is drawn from the
``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import erf, erfc

#: Ring beacons, ring radius (m) and id of the bow beacon of the standard deck.
N_RING = 12
RING_RADIUS_M = 10.0

#: Channel shares of a beacon's electrons (R, G, B): white, and the red bow LED.
WHITE = (1 / 3, 1 / 3, 1 / 3)
RED = (0.90, 0.07, 0.03)
GREEN = (0.05, 0.85, 0.10)
#: Brightness of a red LED on a mono sensor relative to the same electrons of white light.
MONO_RED_FACTOR = 0.43


@dataclass(frozen=True)
class SpotFrameSpec:
    """What one family of independent frames looks like.

    Attributes
    ----------
    width_px, height_px : int
        Image size.
    rgb : bool
        Three channels (RGB) or one (mono).
    bits : int
        8, 12 (stored in 16-bit, full scale 4095 scaled to 65535) or 16.
    sigma_px : (float, float)
        Range of the spot's Gaussian sigma, pixels (drawn uniformly per beacon).
    flux_e : (float, float)
        Range of a beacon's electrons summed over channels (drawn log-uniformly).
    uneven : (float, float)
        Each beacon's flux is multiplied by U(lo, hi) (LED tolerance, viewing angle).
    bow_factor : float
        The bow's flux relative to a ring beacon's (before ``uneven``).
    background_e : float
        Sky/sea background per pixel and channel, electrons.
    read_noise_e : float
        Read noise per pixel and channel, electrons.
    full_well_e : float
        Electrons at full scale (per channel).
    saturate : bool
        Clip at full scale (otherwise ``full_well_e`` is raised until no pixel clips).
    missing_ring : int
        Ring beacons removed (never the bow).
    drop_centre : bool
        Remove the centre beacon.
    drop_bow : bool
        Remove the bow beacon (a frame that cannot be identified).
    flux_override : tuple of (int, float)
        ``(beacon id, electrons)`` pairs that replace those beacons' drawn flux.
    other_lights : int
        Non-beacon lights placed off the ring (navigation lights, floodlights, glints).
    height_m : (float, float)
        Camera height above the deck, metres.
    tilt_deg : float
        Largest camera tilt from nadir, degrees.
    focal_px : float
        Focal length, pixels (square pixels, principal point at the centre).
    """

    width_px: int = 3840
    height_px: int = 2160
    rgb: bool = True
    bits: int = 12
    sigma_px: tuple[float, float] = (0.8, 2.5)
    flux_e: tuple[float, float] = (3_000.0, 30_000.0)
    uneven: tuple[float, float] = (1.0, 1.0)
    bow_factor: float = 1.0
    background_e: float = 30.0
    read_noise_e: float = 5.0
    full_well_e: float = 20_000.0
    saturate: bool = False
    missing_ring: int = 0
    drop_centre: bool = False
    drop_bow: bool = False
    flux_override: tuple[tuple[int, float], ...] = ()
    other_lights: int = 0
    height_m: tuple[float, float] = (35.0, 60.0)
    tilt_deg: float = 5.0
    focal_px: float = 2500.0

    def __post_init__(self) -> None:
        if self.bits not in (8, 12, 16):
            raise ValueError(f"bits must be 8, 12 or 16, got {self.bits}")
        if not 0 <= self.missing_ring <= N_RING - 5:
            raise ValueError("missing_ring must leave at least 5 ring beacons")


@dataclass(frozen=True)
class SpotFrame:
    """One independent frame and its truth.

    Attributes
    ----------
    image : (H, W, 3) or (H, W) array of uint8 or uint16
    K : (3, 3) array of float
        Camera matrix (no distortion).
    beacon_id : (M,) array of int
        Ids of the beacons in the image (ring ``0..11`` from the bow, centre 12).
    centre_px : (M, 2) array of float
        Exact spot centres ``(u, v)``, pixel centres at integers.
    crb_px : (M, 2) array of float
        Per-axis centroid Cramér–Rao bound of the channel-sum image, pixels.
    sigma_px, flux_e : (M,) arrays of float
        Each beacon's spot sigma and electrons (channel sum).
    saturated : (M,) array of bool
        A pixel of the spot reached full scale.
    lights_px : (L, 2) array of float
        Centres of the other lights.
    lights_kind : list of str
    gain_dn_per_e : float
        DN per electron of the stored image.
    """

    image: np.ndarray
    K: np.ndarray
    beacon_id: np.ndarray
    centre_px: np.ndarray
    crb_px: np.ndarray
    sigma_px: np.ndarray
    flux_e: np.ndarray
    saturated: np.ndarray
    lights_px: np.ndarray
    lights_kind: list[str] = field(default_factory=list)
    gain_dn_per_e: float = 1.0


def _rot(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch),
                              math.sin(pitch), math.cos(yaw), math.sin(yaw))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def beacon_points_deck() -> np.ndarray:
    """Beacons in the deck frame (x bow, y port, z up), (13, 3) metres; centre last."""
    a = 2 * np.pi * np.arange(N_RING) / N_RING
    ring = np.column_stack([RING_RADIUS_M * np.cos(a), RING_RADIUS_M * np.sin(a), np.zeros(N_RING)])
    return np.vstack([ring, np.zeros((1, 3))])


def project(points_deck: np.ndarray, K: np.ndarray, height_m: float, R_tilt: np.ndarray,
            deck_yaw_rad: float) -> np.ndarray:
    """Pixels of deck points seen by a camera ``height_m`` above the deck centre.

    The camera looks straight down (image top toward the bow at zero yaw) and
    is then tilted by ``R_tilt`` about its own centre; the deck is yawed by
    ``deck_yaw_rad``.
    """
    # nadir camera: x_cam = -y_deck (right = starboard), y_cam = -x_deck (down = stern),
    # z_cam = -z_deck (down)
    R_nadir = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    R_cam_from_deck = R_tilt @ R_nadir @ _rot(0.0, 0.0, deck_yaw_rad)
    cam_pos_deck = np.array([0.0, 0.0, height_m])
    pc = (points_deck - cam_pos_deck) @ R_cam_from_deck.T
    uvw = pc @ K.T
    return uvw[:, :2] / uvw[:, 2:3]


def spot_profile(centre: float, sigma: float, coords: np.ndarray) -> np.ndarray:
    """Fraction of a 1-D Gaussian falling in unit pixels centred on ``coords``."""
    s = sigma * math.sqrt(2.0)
    return 0.5 * (erf((coords + 0.5 - centre) / s) - erf((coords - 0.5 - centre) / s))


def spot_derivative(centre: float, sigma: float, coords: np.ndarray) -> np.ndarray:
    """d/d(centre) of :func:`spot_profile` (difference of the Gaussian density at the edges)."""
    g = lambda x: np.exp(-0.5 * (x / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
    return g(coords - 0.5 - centre) - g(coords + 0.5 - centre)


def _half(sigma: float) -> int:
    return math.ceil(6.0 * sigma) + 2


def make_frame(spec: SpotFrameSpec, rng: np.random.Generator) -> SpotFrame:
    """Draw one frame of ``spec`` (see the module docstring)."""
    W, H = spec.width_px, spec.height_px
    K = np.array([[spec.focal_px, 0.0, (W - 1) / 2], [0.0, spec.focal_px, (H - 1) / 2], [0, 0, 1]])
    # geometry: redraw until the whole ring is inside the image with a margin
    for _ in range(200):
        h = rng.uniform(*spec.height_m)
        t = math.radians(spec.tilt_deg)
        R_tilt = _rot(rng.uniform(-t, t), rng.uniform(-t, t), 0.0)
        uv = project(beacon_points_deck(), K, h, R_tilt, rng.uniform(-math.pi, math.pi))
        if np.all((uv[:, 0] > 30) & (uv[:, 0] < W - 31) & (uv[:, 1] > 30) & (uv[:, 1] < H - 31)):
            break
    else:
        raise ValueError("the ring does not fit the image at these heights; lower focal_px")
    ids = np.arange(N_RING + 1)
    keep = np.ones(N_RING + 1, bool)
    if spec.missing_ring:
        keep[rng.choice(np.arange(1, N_RING), spec.missing_ring, replace=False)] = False
    if spec.drop_centre:
        keep[N_RING] = False
    if spec.drop_bow:
        keep[0] = False
    ids, uv = ids[keep], uv[keep]
    m = ids.size
    sigma = rng.uniform(*spec.sigma_px, m)
    flux = np.exp(rng.uniform(*np.log(spec.flux_e), m)) * rng.uniform(*spec.uneven, m)
    flux[ids == 0] *= spec.bow_factor
    for bid, f_e in spec.flux_override:
        flux[ids == bid] = f_e
    colours = [RED if i == 0 else WHITE for i in ids]
    # other lights, away from every beacon and from the ring ellipse
    centre = uv[ids == N_RING][0] if (ids == N_RING).any() else uv[ids < N_RING].mean(axis=0)
    if spec.other_lights and not (ids == N_RING).any():  # the ring's centre, not its mean
        centre = project(np.zeros((1, 3)), K, h, R_tilt, 0.0)[0]
    r_img = float(np.median(np.linalg.norm(uv[ids < N_RING] - centre, axis=1)))
    lights, kinds, l_sigma, l_flux, l_col = [], [], [], [], []
    kinds_cycle = ["red sidelight", "green sidelight", "floodlight", "glint", "floodlight"]
    while len(lights) < spec.other_lights:
        p = rng.uniform([40, 40], [W - 41, H - 41])
        rr = np.linalg.norm(p - centre)
        if abs(rr - r_img) < 0.25 * r_img or np.min(np.linalg.norm(uv - p, axis=1)) < 0.3 * r_img:
            continue
        if lights and np.min(np.linalg.norm(np.array(lights) - p, axis=1)) < 20:
            continue
        k = kinds_cycle[len(lights) % len(kinds_cycle)]
        lights.append(p)
        kinds.append(k)
        l_sigma.append(rng.uniform(*spec.sigma_px) * (2.0 if k == "floodlight" else 1.0))
        l_flux.append(rng.uniform(*spec.flux_e) * (3.0 if k == "floodlight" else 1.0))
        l_col.append({"red sidelight": RED, "green sidelight": GREEN}.get(k, WHITE))

    n_ch = 3 if spec.rgb else 1
    mu = np.full((H, W, n_ch), spec.background_e, np.float64)
    all_pts = list(uv) + lights
    all_sig = list(sigma) + l_sigma
    all_flux = list(flux) + l_flux
    all_col = colours + l_col
    for (u, v), s, f, col in zip(all_pts, all_sig, all_flux, all_col):
        r = _half(s)
        u0, u1 = max(0, int(u) - r), min(W, int(u) + r + 1)
        v0, v1 = max(0, int(v) - r), min(H, int(v) + r + 1)
        patch = np.outer(spot_profile(v, s, np.arange(v0, v1, dtype=float)),
                         spot_profile(u, s, np.arange(u0, u1, dtype=float)))
        if spec.rgb:
            mu[v0:v1, u0:u1] += f * patch[..., None] * np.asarray(col)[None, None, :]
        else:
            grey = MONO_RED_FACTOR if col is RED else 1.0
            mu[v0:v1, u0:u1, 0] += f * grey * patch
    full_scale_dn = {8: 255.0, 12: 65535.0, 16: 65535.0}[spec.bits]
    full_well = spec.full_well_e
    if not spec.saturate:
        full_well = max(full_well, float(mu.max()) + 8 * math.sqrt(float(mu.max())) + 50.0)
    gain = full_scale_dn / full_well
    e = rng.poisson(mu).astype(np.float64) + rng.normal(0.0, spec.read_noise_e, mu.shape)
    dn = np.clip(np.rint(e * gain), 0, full_scale_dn)
    if spec.bits == 12:  # 12-bit data scaled to 16 bits: steps of 16 DN
        dn = np.clip(np.rint(e * gain / 16.0) * 16.0, 0, 65520.0)
    img = dn.astype(np.uint8 if spec.bits == 8 else np.uint16)
    if not spec.rgb:
        img = img[..., 0]

    # truth: CRB of the channel-sum image (mean and variance summed over channels), electrons
    crb = np.zeros((m, 2))
    sat = np.zeros(m, bool)
    for i, ((u, v), s, f, col) in enumerate(zip(uv, sigma, flux, colours)):
        r = _half(s)
        u0, u1 = max(0, int(u) - r), min(W, int(u) + r + 1)
        v0, v1 = max(0, int(v) - r), min(H, int(v) + r + 1)
        xs, ys = np.arange(u0, u1, dtype=float), np.arange(v0, v1, dtype=float)
        px, py = spot_profile(u, s, xs), spot_profile(v, s, ys)
        dx, dy = spot_derivative(u, s, xs), spot_derivative(v, s, ys)
        grey = 1.0 if spec.rgb or col is not RED else MONO_RED_FACTOR
        # Poisson + read noise + rounding to the stored DN step (1/12 step^2), electrons^2
        step_e = (16.0 if spec.bits == 12 else 1.0) / gain
        var = mu[v0:v1, u0:u1].sum(axis=2) + n_ch * (spec.read_noise_e**2 + step_e**2 / 12.0)
        d_u = f * grey * np.outer(py, dx)
        d_v = f * grey * np.outer(dy, px)
        F = np.array([[np.sum(d_u * d_u / var), np.sum(d_u * d_v / var)],
                      [np.sum(d_u * d_v / var), np.sum(d_v * d_v / var)]])
        crb[i] = np.sqrt(np.diag(np.linalg.inv(F)))
        block = img[v0:v1, u0:u1]
        sat[i] = bool(np.any(block >= (full_scale_dn if spec.bits != 12 else 65520)))
    return SpotFrame(img, K, ids, uv, crb, sigma, flux * np.where(
        (ids == 0) & (not spec.rgb), MONO_RED_FACTOR, 1.0), sat,
        np.array(lights, float).reshape(-1, 2), kinds, gain)


def expected_dn(mu_e: np.ndarray, read_e: float, gain_dn_per_e: float, step_dn: float = 1.0) -> np.ndarray:
    """E[DN] of pixels of ``mu_e`` expected electrons after the sensor's rounding to ``step_dn``.

    The electrons are taken as normal, of mean and variance ``mu_e`` plus the read noise's
    (Poisson's mean and variance), rounded to whole steps; full scale is not applied.
    """
    mu = np.asarray(mu_e, float)
    sd = np.sqrt(mu + read_e**2)
    scale = gain_dn_per_e / step_dn  # steps per electron
    return step_dn * sum(0.5 * erfc(((k - 0.5) / scale - mu) / (sd * math.sqrt(2.0))) for k in range(1, 60))


def visible_dn(truth: SpotFrame, spec: SpotFrameSpec) -> np.ndarray:
    """Each beacon's expected DN above the background after rounding, over its pixels and channels, (M,).

    What the stored frame holds of a beacon's light: on a dark 8-bit frame whose noise does
    not dither the rounding, a wing pixel of 0.3 DN stores 0 DN, and a beacon of some
    thousand electrons can round away altogether (no detector can find it). Computed from
    the spot model and :func:`expected_dn` (at most 59 steps a pixel: for dark frames).
    """
    step = 16.0 if spec.bits == 12 else 1.0
    bg = float(expected_dn(np.array(spec.background_e), spec.read_noise_e, truth.gain_dn_per_e, step))
    out = []
    for (u, v), s, f, bid in zip(truth.centre_px, truth.sigma_px, truth.flux_e, truth.beacon_id):
        r = _half(s)
        xs = np.arange(int(u) - r, int(u) + r + 1, dtype=float)
        ys = np.arange(int(v) - r, int(v) + r + 1, dtype=float)
        prof = np.outer(spot_profile(v, s, ys), spot_profile(u, s, xs))
        if spec.rgb:
            light = f * prof[..., None] * np.asarray(RED if bid == 0 else WHITE)
        else:
            light = f * (MONO_RED_FACTOR if bid == 0 else 1.0) * prof[..., None]
        dn = expected_dn(spec.background_e + light, spec.read_noise_e, truth.gain_dn_per_e, step)
        out.append(float(np.sum(dn - bg)))
    return np.array(out)


def match(points_px: np.ndarray, truth: SpotFrame, tol_px: float = 3.0
          ) -> tuple[np.ndarray, np.ndarray]:
    """Nearest detection per true beacon: ``(index or -1 per beacon, distance)``."""
    pts = np.asarray(points_px, float).reshape(-1, 2)
    idx = np.full(truth.beacon_id.size, -1)
    dist = np.full(truth.beacon_id.size, np.inf)
    if pts.size == 0:
        return idx, dist
    d = np.linalg.norm(truth.centre_px[:, None, :] - pts[None], axis=2)
    taken: set[int] = set()
    for i in np.argsort(d.min(axis=1)):
        j = int(np.argmin(d[i]))
        if d[i, j] <= max(tol_px, 3 * truth.sigma_px[i]) and j not in taken:
            idx[i], dist[i] = j, d[i, j]
            taken.add(j)
    return idx, dist
