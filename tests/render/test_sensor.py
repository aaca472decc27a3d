"""Statistics of the sensor model (:func:`deckpose.render.sensor.expose`) against its definition.

The model: a pixel of mean ``mu`` DN reads ``clip(round(mu + sigma z), 0, 2**bits - 1)``
with ``z`` standard normal and ``sigma**2 = g mu + (g r)**2`` (shot + read noise, ``g`` DN
per electron, ``r`` the read noise in electrons). The reference moments below are that
law's exact moments (a sum over the DN values), the same for the model before and after
the rewrite of issue 20 (the noise realisation changed, not its law). Each sample moment
over ``N`` values must lie within :data:`N_SE` standard errors of the reference, the
standard errors computed from ``N`` and the law's own second and fourth moments.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from deckpose.render import sensor as sensor_module
from deckpose.render.beacons import Splat
from deckpose.render.config import SensorSpec
from deckpose.render.sensor import expose
from numpy.typing import NDArray
from scipy.special import ndtr

#: Standard errors a sample moment may lie from the reference: a false alarm has
#: probability ~6e-7 per check (normal), a wrong model (1 % off in sigma at 1e6 values:
#: ~7 standard errors of the variance) fails.
N_SE = 5.0
#: Flat-field size: 600 x 500 pixels (300 000 values per channel).
SHAPE = (600, 500)
LUMA = np.array([0.299, 0.587, 0.114])


def law_moments(mu_dn: float, sigma_dn: float, dn_max: int) -> tuple[float, float, float]:
    """Mean, variance and fourth central moment of ``clip(round(N(mu, sigma^2)), 0, dn_max)``."""
    k = np.arange(dn_max + 1, dtype=float)
    if sigma_dn == 0:
        p = (k == np.clip(np.rint(mu_dn), 0, dn_max)).astype(float)
    else:
        upper = ndtr((k + 0.5 - mu_dn) / sigma_dn)
        upper[-1] = 1.0
        lower = np.concatenate([[0.0], upper[:-1]])
        p = upper - lower
    mean = float(p @ k)
    var = float(p @ (k - mean) ** 2)
    m4 = float(p @ (k - mean) ** 4)
    return mean, var, m4


def assert_moments(values: NDArray[np.floating], mu_dn: float, sigma_dn: float, dn_max: int,
                   what: str) -> None:
    """Sample mean and variance of ``values`` within N_SE standard errors of the law's."""
    n = values.size
    mean, var, m4 = law_moments(mu_dn, sigma_dn, dn_max)
    se_mean = np.sqrt(var / n)
    se_var = np.sqrt(max(m4 - var ** 2, 0.0) / n + 2 * var ** 2 / (n * (n - 1)))
    got_mean = float(values.mean())
    got_var = float(values.var(ddof=1))
    assert abs(got_mean - mean) <= N_SE * se_mean + 1e-9 * max(mean, 1.0), (
        f"{what}: mean {got_mean:.6g} DN, law {mean:.6g} +- {se_mean:.3g} (1 SE)")
    assert abs(got_var - var) <= N_SE * se_var + 1e-9 * max(var, 1.0), (
        f"{what}: variance {got_var:.6g} DN^2, law {var:.6g} +- {se_var:.3g} (1 SE)")


def flat_field(sensor: SensorSpec, levels: tuple[float, float, float],
               seed: int) -> tuple[NDArray[np.float64], list[float], list[float]]:
    """A white raster exposed so channel c holds ``levels[c]`` x full well (mono: their luma).

    Returns the image (float), and each channel's mean and sigma in DN under the model.
    """
    scale = (np.array(levels) / 255.0).astype(np.float32)
    raster = np.full((*SHAPE, 3), 255, np.uint8)
    img = expose(raster, scale, [], sensor, np.random.default_rng(seed)).astype(float)
    dn_max = 2 ** sensor.bit_depth - 1
    g = dn_max / sensor.full_well_e
    e = 255.0 * scale.astype(float) * sensor.exposure * sensor.full_well_e  # electrons, per channel
    if sensor.color == "mono":
        e = np.array([e @ LUMA.astype(np.float32)])
    mu = [float(x) * g for x in e]
    sigma = [float(np.sqrt(x + sensor.read_noise_e ** 2)) * g if sensor.noise else 0.0 for x in e]
    return img, mu, sigma


#: Signal levels (fraction of the full well) per channel: a few electrons (2, 5 and 20 e- of
#: 20 000), dark / low / mid, and bright / near the full well (the clip at 2**bits - 1 shapes
#: the law) / over it (every value clips).
LEVELS = [(1e-4, 2.5e-4, 1e-3), (0.0, 0.002, 0.3), (0.6, 0.995, 1.2)]


@pytest.mark.parametrize("bit_depth", [8, 12, 16])
@pytest.mark.parametrize("levels", LEVELS)
def test_rgb_flat_field_moments_follow_the_law(bit_depth: int,
                                                levels: tuple[float, float, float]) -> None:
    sensor = SensorSpec(bit_depth=bit_depth)
    img, mu, sigma = flat_field(sensor, levels, seed=11)
    assert img.shape == (*SHAPE, 3)
    for c in range(3):
        assert_moments(img[..., c], mu[c], sigma[c], 2 ** bit_depth - 1,
                       f"{bit_depth}-bit channel {c} at {levels[c]} full well")


@pytest.mark.parametrize("bit_depth", [8, 12, 16])
@pytest.mark.parametrize("level", [0.0, 2.5e-4, 0.002, 0.3, 0.995, 1.2])
def test_mono_flat_field_moments_follow_the_law(bit_depth: int, level: float) -> None:
    sensor = SensorSpec(bit_depth=bit_depth, color="mono", read_noise_e=12.0)
    img, mu, sigma = flat_field(sensor, (level, level, level), seed=12)
    assert img.shape == SHAPE
    assert_moments(img, mu[0], sigma[0], 2 ** bit_depth - 1,
                   f"{bit_depth}-bit mono at {level} full well")


def law_probabilities(mu_dn: float, sigma_dn: float, dn_max: int) -> NDArray[np.float64]:
    """P(value = k), k = 0 .. dn_max, of ``clip(round(N(mu, sigma^2)), 0, dn_max)``."""
    k = np.arange(dn_max + 1, dtype=float)
    upper = ndtr((k + 0.5 - mu_dn) / sigma_dn)
    upper[-1] = 1.0
    return np.diff(np.concatenate([[0.0], upper]))


@pytest.mark.parametrize("electrons", [0.0, 3.0, 12.0])
def test_low_count_distribution_is_the_law(electrons: float) -> None:
    """At 0, 3 and 12 e- (16 bits: 3.3 DN per electron, so the law's shape is resolved) the
    frequency of every value is the law's, the clip at 0 included: each of the values holding
    the central 99.99 % of the law (and the rest pooled as one bin) lies within N_SE binomial
    standard errors of its probability; over ~60 bins a false alarm has probability ~4e-5.
    The third central moment (the clip's skew) agrees with the law's within N_SE of its SE."""
    sensor = SensorSpec(bit_depth=16, color="mono", read_noise_e=5.0)
    dn_max = 2 ** 16 - 1
    g = dn_max / sensor.full_well_e
    level = electrons / sensor.full_well_e
    img, mu, sigma = flat_field(sensor, (level, level, level), seed=14)
    values = img.ravel().astype(np.int64)
    n = values.size
    p = law_probabilities(mu[0], sigma[0], dn_max)
    assert abs(mu[0] - electrons * g) < 1e-3 and abs(sigma[0] - np.sqrt(electrons + 25.0) * g) < 1e-3
    cdf = np.cumsum(p)
    lo, hi = int(np.searchsorted(cdf, 5e-5)), int(np.searchsorted(cdf, 1 - 5e-5))
    counts = np.bincount(values, minlength=dn_max + 1)
    bins_p = np.concatenate([p[lo:hi + 1], [p[:lo].sum() + p[hi + 1:].sum()]])
    bins_n = np.concatenate([counts[lo:hi + 1], [counts[:lo].sum() + counts[hi + 1:].sum()]])
    for i, (pk, nk) in enumerate(zip(bins_p, bins_n, strict=True)):
        se = np.sqrt(n * pk * (1 - pk))
        assert abs(nk - n * pk) <= N_SE * se + 1.0, (
            f"{electrons} e-: bin {i} ({'tails' if i == len(bins_p) - 1 else lo + i} DN) "
            f"count {nk}, law {n * pk:.1f} +- {se:.1f}")
    k = np.arange(dn_max + 1, dtype=float)
    mean = float(p @ k)
    m3 = float(p @ (k - mean) ** 3)
    se_m3 = np.sqrt(max(float(p @ (k - mean) ** 6) - m3 ** 2, 0.0) / n)
    got_m3 = float(np.mean((values - values.mean()) ** 3))
    assert abs(got_m3 - m3) <= N_SE * se_m3, f"{electrons} e-: third moment {got_m3:.4g}, law {m3:.4g} +- {se_m3:.3g}"


@pytest.mark.parametrize(("bit_depth", "dtype"), [(8, np.uint8), (12, np.uint16), (16, np.uint16)])
def test_dtype_range_and_saturation(bit_depth: int, dtype: type) -> None:
    """Integer DN in the output type, 12-bit within 0..4095; far over full well all values clip."""
    dn_max = 2 ** bit_depth - 1
    sensor = SensorSpec(bit_depth=bit_depth, read_noise_e=50.0)
    raster = np.full((40, 50, 3), 255, np.uint8)
    over = expose(raster, np.full(3, 20.0 / 255, np.float32), [], sensor, np.random.default_rng(0))
    assert over.dtype == dtype and np.all(over == dn_max)
    dark = expose(np.zeros_like(raster), np.full(3, 1.0 / 255, np.float32), [], sensor,
                  np.random.default_rng(0))
    assert dark.dtype == dtype and dark.min() == 0  # negative reads clip at 0
    mono = expose(raster, np.full(3, 0.999 / 255, np.float32), [],
                  dataclasses.replace(sensor, color="mono"), np.random.default_rng(0))
    assert mono.dtype == dtype and mono.shape == (40, 50) and mono.max() == dn_max


@pytest.mark.parametrize("bit_depth", [8, 12, 16])
@pytest.mark.parametrize("color", ["rgb", "mono"])
def test_noise_free_image_is_the_rounded_mean(bit_depth: int, color: str) -> None:
    """``noise: false``: every pixel is its mean DN rounded to the nearest integer, then clipped."""
    sensor = SensorSpec(bit_depth=bit_depth, color=color, noise=False)
    raster = np.random.default_rng(1).integers(0, 256, (64, 96, 3), np.uint8)
    scale = np.array([0.9, 0.7, 1.1], np.float32) / 255
    img = expose(raster, scale, [], sensor, np.random.default_rng(0))
    dn_max = 2 ** bit_depth - 1
    e_per_unit = scale.astype(float) * sensor.full_well_e  # electrons per raster unit
    if color == "mono":
        grey = cv2.cvtColor(raster, cv2.COLOR_RGB2GRAY).astype(float)  # the model's mono raster
        mean_dn = grey * float(e_per_unit @ LUMA.astype(np.float32)) * dn_max / sensor.full_well_e
    else:
        mean_dn = raster * e_per_unit * dn_max / sensor.full_well_e
    want = np.clip(np.rint(mean_dn), 0, dn_max)
    # the model's float32 mean (the DN per raster unit rounded to float32, then the product:
    # two roundings, 2**-23 + 2**-48 relative at most) may round a half either way
    near_half = np.abs(mean_dn - np.floor(mean_dn) - 0.5) <= mean_dn * 2.0 ** -22
    assert img.dtype == (np.uint8 if bit_depth == 8 else np.uint16)
    np.testing.assert_array_equal(img[~near_half], want[~near_half])


def test_same_seed_same_frame() -> None:
    """A frame is a function of its generator's state (and its shape): same seed, same frame."""
    sensor = SensorSpec(bit_depth=16)
    raster = np.random.default_rng(2).integers(0, 256, (300, 211, 3), np.uint8)
    scale = np.full(3, 1.0 / 255, np.float32)
    a = expose(raster, scale, [], sensor, np.random.default_rng(7))
    b = expose(raster, scale, [], sensor, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, expose(raster, scale, [], sensor, np.random.default_rng(8)))
    rng = np.random.default_rng(7)
    first = expose(raster, scale, [], sensor, rng)
    np.testing.assert_array_equal(first, a)
    assert not np.array_equal(first, expose(raster, scale, [], sensor, rng))  # the state advanced


@pytest.mark.parametrize("strip_elements", [1, 603, 2 ** 22])
def test_any_strip_size_gives_the_law(monkeypatch: pytest.MonkeyPatch, strip_elements: int) -> None:
    """One-row strips, strips of an odd number of values (a Box-Muller pair left half used)
    and one strip for the whole frame all give the law's moments."""
    monkeypatch.setattr(sensor_module, "STRIP_ELEMENTS", strip_elements)
    sensor = SensorSpec(bit_depth=16, color="mono")
    raster = np.full((401, 201, 3), 255, np.uint8)  # odd width: 3 rows of 201 values = 603
    scale = np.full(3, 0.3 / 255, np.float32)
    img = expose(raster, scale, [], sensor, np.random.default_rng(4)).astype(float)
    g = (2 ** 16 - 1) / sensor.full_well_e
    e = 255 * float(scale[0]) * float(LUMA.astype(np.float32).sum()) * sensor.full_well_e
    assert_moments(img, e * g, float(np.sqrt(e + sensor.read_noise_e ** 2)) * g, 2 ** 16 - 1,
                   f"strips of {strip_elements} values")


def test_noise_is_white_and_normal() -> None:
    """Neighbours along a row, down a column (across strip boundaries) and across channels
    are uncorrelated (each correlation within N_SE / sqrt(N) of zero); the standardised
    noise has the normal law's skewness (0), kurtosis (3) and tails beyond 3 and 4 sigma.
    (16 bits at 0.3 full well: sigma is 250 DN, so rounding changes these by < 1e-5.)"""
    sensor = SensorSpec(bit_depth=16)
    img, mu, sigma = flat_field(sensor, (0.3, 0.3, 0.3), seed=13)
    r = img - np.array(mu)
    pairs = {
        "along rows": (r[:, 1:], r[:, :-1]),
        "down columns": (r[1:], r[:-1]),
        "R-G": (r[..., 0], r[..., 1]),
        "G-B": (r[..., 1], r[..., 2]),
    }
    for name, (x, y) in pairs.items():
        rho = float(np.corrcoef(x.ravel(), y.ravel())[0, 1])
        assert abs(rho) < N_SE / np.sqrt(x.size), f"{name}: correlation {rho:.2e}"
    z = (r / np.array(sigma)).ravel()
    n = z.size
    skew, kurt = float(np.mean(z ** 3)), float(np.mean(z ** 4))
    assert abs(skew) < N_SE * np.sqrt(15.0 / n), f"skewness {skew:.4f}"
    assert abs(kurt - 3.0) < N_SE * np.sqrt(96.0 / n), f"kurtosis {kurt:.4f}"
    for k in (3.0, 4.0):
        p = float(2 * ndtr(-k))
        got = float(np.mean(np.abs(z) > k))
        assert abs(got - p) < N_SE * np.sqrt(p * (1 - p) / n), (
            f"P(|z| > {k}) {got:.3g}, law {p:.3g}")


def _gaussian_splat(row0: int, col0: int, size: int, sigma_px: float, peak: float) -> Splat:
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    patch = (peak * np.exp(-(xx ** 2 + yy ** 2) / (2 * sigma_px ** 2))).astype(np.float32)
    rgb = np.array([1.0, 0.8, 0.6], np.float32)
    return Splat(row0, col0, patch, rgb, 0, sigma_px, float(patch.sum()))


def test_beacons_are_not_shifted_and_carry_their_shot_noise() -> None:
    """Over K frames each pixel's mean is its expected signal (z-scores of mean 0, variance 1),
    inside the beacon windows too, where sigma follows the beacon light; the mean image's
    beacon centroid is the noise-free one."""
    sensor = SensorSpec(bit_depth=16, read_noise_e=5.0, full_well_e=20000.0)
    H, W, K = 64, 80, 60
    raster = np.full((H, W, 3), 40, np.uint8)
    scale = np.full(3, 0.05 / 255, np.float32)  # background ~ 157 e per channel
    splats = [_gaussian_splat(10, 12, 21, 2.2, 0.3), _gaussian_splat(30, 47, 25, 3.0, 0.5)]
    g = (2 ** 16 - 1) / sensor.full_well_e
    e = np.full((H, W, 3), 40.0 * float(scale[0]) * sensor.full_well_e)
    for sp in splats:
        n = sp.patch.shape[0]
        light_e = sp.patch[..., None] * sp.rgb * sensor.full_well_e
        e[sp.row0:sp.row0 + n, sp.col0:sp.col0 + n] += light_e
    mu = e * g
    sigma = np.sqrt(e + sensor.read_noise_e ** 2) * g
    assert mu.max() + 6 * sigma.max() < 2 ** 16 - 1  # unsaturated, so the mean is unclipped
    rng = np.random.default_rng(21)
    frames = np.stack([expose(raster, scale, splats, sensor, rng) for _ in range(K)]).astype(float)
    # 16-bit rounding adds 1/12 DN^2 to the variance: ~1e-5 of sigma^2 here, neglected
    z = (frames.mean(axis=0) - mu) / (sigma / np.sqrt(K))
    n = z.size
    assert abs(z.mean()) < N_SE / np.sqrt(n), f"mean z {z.mean():.3g}"
    assert abs(z.var() - 1.0) < N_SE * np.sqrt(2.0 / n), f"var z {z.var():.4f}"
    in_beacon = (e - e.min()) > 0.2 * (e.max() - e.min())
    zb = z[in_beacon]
    assert abs(zb.mean()) < N_SE / np.sqrt(zb.size), f"mean z in beacons {zb.mean():.3g}"
    assert abs(zb.var() - 1.0) < N_SE * np.sqrt(2.0 / zb.size), f"var z in beacons {zb.var():.4f}"
    # centroid of the first beacon's light (channel sum, less the background) in the mean image
    # vs in the expectation, within N_SE of its standard error (from sigma of the mean image)
    win = (slice(10, 31), slice(12, 33))
    background = mu[0, 0].sum()
    light = frames.mean(axis=0)[win].sum(axis=2) - background
    want = mu[win].sum(axis=2) - background
    var_mean = (sigma[win] ** 2).sum(axis=2) / K
    vv, uu = np.mgrid[win]
    for coord in (uu, vv):
        c_want = (want * coord).sum() / want.sum()
        c_got = (light * coord).sum() / light.sum()
        se = np.sqrt((var_mean * (coord - c_want) ** 2).sum()) / want.sum()
        assert abs(c_got - c_want) < N_SE * se, (
            f"centroid {c_got:.4f} px, want {c_want:.4f} +- {se:.1e}")


#: Pixels per raster level in :func:`test_every_level_follows_the_law` (256 levels: 2 MP).
PER_LEVEL = 2048
#: A group's sample moments are checked one by one only where the sample is large against
#: the law's kurtosis (``n >= KURTOSIS_FACTOR * m4 / var**2``), i.e. where their normal
#: approximation holds: an 8-bit level of sigma ~0.1 DN is a rare-event (Poisson-like) count
#: whose 5-SE tail is far heavier than the normal's. Every group enters the pooled checks.
KURTOSIS_FACTOR = 100.0


def law_moments_near(mu_dn: float, sigma_dn: float, dn_max: int) -> tuple[float, float, float]:
    """:func:`law_moments` summed over the values within 10 sigma of ``mu_dn`` only (the rest
    of the law's mass is below 2e-23): a 16-bit level costs a few thousand terms, not 65 536."""
    lo = int(np.clip(np.floor(mu_dn - 10 * sigma_dn), 0, dn_max))
    hi = int(np.clip(np.ceil(mu_dn + 10 * sigma_dn), 0, dn_max))
    k = np.arange(lo, hi + 1, dtype=float)
    cdf = ndtr((np.arange(lo, hi + 2) - 0.5 - mu_dn) / sigma_dn)  # P(x < k - 0.5), k = lo .. hi + 1
    cdf[0] = 0.0 if lo == 0 else cdf[0]
    cdf[-1] = 1.0 if hi == dn_max else cdf[-1]
    p = np.diff(cdf)
    mean = float(p @ k)
    d2 = (k - mean) ** 2
    return mean, float(p @ d2), float(p @ (d2 * d2))


def _group_moments(values: NDArray[np.floating], labels: NDArray[np.intp],
                   n_groups: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Count, sample mean and sample variance (ddof 1) of ``values`` per label."""
    n = np.bincount(labels, minlength=n_groups).astype(float)
    s1 = np.bincount(labels, values, minlength=n_groups)
    mean = s1 / n
    dev = values - mean[labels]
    var = np.bincount(labels, dev * dev, minlength=n_groups) / (n - 1)
    return n, mean, var


@pytest.mark.parametrize("bit_depth", [8, 16])
@pytest.mark.parametrize("color", ["rgb", "mono"])
def test_every_level_follows_the_law(bit_depth: int, color: str) -> None:
    """Mean and variance of each raster level (0..255) and channel, and of a splat window,
    against the law: mean ``mu``, ``sigma**2 = g mu + (g r)**2`` before rounding, and the exact
    moments of ``clip(round(N(mu, sigma**2)))`` after (for sigma of a few DN and more, that is
    ``sigma**2 + 1/12`` DN^2, rounding's variance; 8-bit sigma is 0.06-1.4 DN here, where only
    the exact sum is right). Channels' DN per raster unit differ and one channel's top levels
    reach the clip. Each group (``PER_LEVEL`` values, the window ~10 000) is checked within
    N_SE standard errors computed from its size and the law's second and fourth moments: over
    ~1 500 such checks a false alarm has probability ~1e-3. Pooled over all groups, the
    standardised deviations' mean lies within N_SE / sqrt(groups) of 0: a 1 % error of sigma
    moves it by ~10 of those standard errors."""
    sensor = SensorSpec(bit_depth=bit_depth, color=color, read_noise_e=5.0)
    dn_max = 2 ** bit_depth - 1
    g = dn_max / sensor.full_well_e
    rows_levels = 256 * PER_LEVEL // 512
    levels = (np.arange(rows_levels * 512) // PER_LEVEL).reshape(rows_levels, 512)
    H, W = rows_levels + 40, 512
    grey = np.full((H, W), 90, np.uint8)  # a band of level 90 under the splat
    grey[:rows_levels] = levels
    raster = np.repeat(grey[..., None], 3, axis=2)
    scale = np.array([0.4, 0.8, 1.1], np.float32) / 255  # channel 2's top levels clip
    # one splat: a constant patch over 30 x 350 pixels of the band
    patch = np.full((30, 350), 0.2, np.float32)
    rgb = np.array([1.0, 0.7, 0.3], np.float32)
    splat = Splat(rows_levels + 5, 80, patch, rgb, 0, 10.0, float(patch.sum()))
    img = expose(raster, scale, [splat], sensor, np.random.default_rng(31)).astype(float)
    # the model's mean, DN: level x its channel's DN per raster unit (float32, as the model
    # rounds it), plus the splat's light (radiance x exposure x full well x g)
    e_per_unit = scale.astype(np.float64) * sensor.exposure * sensor.full_well_e
    light_e = 0.2 * rgb.astype(np.float64) * sensor.exposure * sensor.full_well_e
    if color == "mono":
        e_per_unit = np.array([e_per_unit @ LUMA.astype(np.float32)])
        light_e = np.array([light_e.mean()])
        img = img[..., None]
    dn_per_unit = (e_per_unit * g).astype(np.float32).astype(np.float64)
    in_window = np.zeros((H, W), bool)
    in_window[splat.row0:splat.row0 + 30, splat.col0:splat.col0 + 350] = True
    labels = np.where(in_window, 256, grey.astype(np.intp))  # 256: the splat window
    groups, mu_groups, sigma_groups, n_all, d_mean, d_var = [], [], [], [], [], []
    for c in range(img.shape[2]):
        n, mean, var = _group_moments(img[..., c].ravel(), labels.ravel(), 257)
        mu = np.concatenate([np.arange(256) * dn_per_unit[c], [90 * dn_per_unit[c] + light_e[c] * g]])
        sigma = np.sqrt(g * mu + (g * sensor.read_noise_e) ** 2)
        for k in range(257):
            if k != 90 or n[k] > 1:  # level 90 keeps the band's pixels outside the window
                groups.append((c, k, n[k], mean[k], var[k]))
                mu_groups.append(mu[k])
                sigma_groups.append(sigma[k])
    assert len(groups) == 257 * img.shape[2]
    for (c, k, n, mean, var), mu, sigma in zip(groups, mu_groups, sigma_groups, strict=True):
        what = f"{bit_depth}-bit {color} channel {c} " + ("splat window" if k == 256 else f"level {k}")
        law_mean, law_var, m4 = law_moments_near(mu, sigma, dn_max)
        se_mean = np.sqrt(law_var / n)
        se_var = np.sqrt(max(m4 - law_var ** 2, 0.0) / n + 2 * law_var ** 2 / (n * (n - 1)))
        if law_var > 0:
            d_mean.append((mean - law_mean) / se_mean)
            d_var.append((var - law_var) / se_var)
        n_all.append(n)
        if law_var == 0 or n >= KURTOSIS_FACTOR * m4 / law_var ** 2:
            assert abs(mean - law_mean) <= N_SE * se_mean + 1e-9 * max(law_mean, 1.0), (
                f"{what}: mean {mean:.6g} DN, law {law_mean:.6g} +- {se_mean:.3g} (1 SE)")
            assert abs(var - law_var) <= N_SE * se_var + 1e-9 * max(law_var, 1.0), (
                f"{what}: variance {var:.6g} DN^2, law {law_var:.6g} +- {se_var:.3g} (1 SE)")
    assert min(n_all) >= 1000
    for name, d in (("mean", d_mean), ("variance", d_var)):
        pooled = float(np.mean(d))
        assert abs(pooled) <= N_SE / np.sqrt(len(d)), (
            f"{bit_depth}-bit {color}: pooled standardised {name} deviation {pooled:.3g} over "
            f"{len(d)} groups, allowed {N_SE / np.sqrt(len(d)):.3g}")
