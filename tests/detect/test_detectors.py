"""Every registered detector on analytic spots with known centres."""

import numpy as np
import pytest
from deckpose.detect import registry
from deckpose.detect.crb import centroid_crb_px2
from deckpose.detect.registry import Blobs, DetectorOptions
from deckpose.detect.synthetic import SensorModel, render_spots

from deckpose.camera import preset
from deckpose.records import Frame

from .conftest import grid_points

SENSOR = SensorModel(gain_dn_per_e=1.0, read_noise_e=3.0, background_e=20.0, bit_depth=16)
SHAPE = (320, 480)
SIGMA_PX, FLUX_E = 1.5, 2e4  # FWHM 3.5 px: "spans at least 2 px"
N_FRAMES = 15


@pytest.fixture(scope="module")
def spot_frames():
    rng = np.random.default_rng(42)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    frames = []
    for k in range(N_FRAMES):
        pts = grid_points(rng, SHAPE, 3, 2)
        frames.append((Frame(render_spots(SHAPE, pts, SIGMA_PX, FLUX_E, SENSOR, rng), cam, k), pts))
    crb = np.mean(
        [
            np.trace(centroid_crb_px2(u, v, SIGMA_PX, FLUX_E, SENSOR)) / 2
            for _, pts in frames
            for u, v in pts
        ]
    )
    return frames, float(np.sqrt(crb))


def _errors(name, frames):
    errs, covs, n_det = [], [], 0
    for frame, pts in frames:
        b = registry.get(name)(frame, DetectorOptions())
        assert b.ok, b.reason
        n_det += len(b)
        d = np.linalg.norm(b.points_px[None] - pts[:, None], axis=2)
        j = d.argmin(axis=1)
        assert np.all(d[np.arange(len(pts)), j] < 1.0), "a spot was missed"
        errs.append(b.points_px[j] - pts)
        covs.append(b.covariance_px2[j])
    return np.concatenate(errs), np.concatenate(covs), n_det


def test_builtin_detectors_are_registered():
    assert {"binary", "cog", "gauss", "log", "opencv-blob"} <= set(registry.names())


@pytest.mark.parametrize("name", ["cog", "gauss", "log"])
def test_subpixel_detectors_reach_the_cramer_rao_bound(name, spot_frames):
    frames, crb = spot_frames
    e, _, n_det = _errors(name, frames)
    assert n_det == 6 * N_FRAMES  # no false positives at the adaptive threshold
    rms = float(np.sqrt(np.mean(e**2)))
    # 180 spots: the RMS has ~4 % sampling error; the target is 1.3x the bound.
    assert 0.8 * crb < rms < 1.3 * crb, (rms, crb)
    assert np.all(np.abs(e.mean(axis=0)) < 3 * crb / np.sqrt(len(e)) + 1e-3)


@pytest.mark.parametrize("name", ["binary", "opencv-blob"])
def test_baseline_detectors_are_subpixel_but_worse(name, spot_frames):
    frames, crb = spot_frames
    e, _, n_det = _errors(name, frames)
    assert n_det == 6 * N_FRAMES
    rms = float(np.sqrt(np.mean(e**2)))
    assert rms < 0.3
    assert rms > 2.0 * crb  # the pixel-threshold centroids cannot approach the bound


@pytest.mark.parametrize("name", ["cog", "gauss"])
def test_reported_covariance_matches_the_errors(name, spot_frames):
    frames, _ = spot_frames
    e, cov, _ = _errors(name, frames)
    # Normalised squared error d^T C^-1 d is chi^2 with 2 dof (mean 2) if C is right;
    # the gain is estimated per frame, so allow +-40 %.
    nees = np.einsum("ni,nij,nj->n", e, np.linalg.inv(cov), e)
    assert 1.2 < nees.mean() < 2.8, nees.mean()


@pytest.mark.parametrize("name", ["binary", "cog", "gauss", "log", "opencv-blob"])
def test_pure_noise_frame_fails_with_a_reason(name):
    rng = np.random.default_rng(7)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    frame = Frame(render_spots(SHAPE, np.zeros((0, 2)), [], [], SENSOR, rng), cam)
    b = registry.get(name)(frame, DetectorOptions())
    assert not b and len(b) == 0
    assert "dark frame" in b.reason or "no" in b.reason


def test_threshold_adapts_to_background_level():
    rng = np.random.default_rng(3)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    pts = grid_points(rng, SHAPE, 3, 2)
    for offset in (0.0, 5000.0):
        sensor = SensorModel(
            gain_dn_per_e=1.0, read_noise_e=3.0, background_e=20.0, offset_dn=offset
        )
        b = registry.get("cog")(
            Frame(render_spots(SHAPE, pts, 1.5, 2e4, sensor, rng), cam), DetectorOptions()
        )
        assert len(b) == 6


def test_coarse_to_fine_finds_small_spots_in_a_large_frame():
    # 2400x1600 with a 100k-pixel coarse image: 5x5 blocks; spots of FWHM 2 px.
    rng = np.random.default_rng(5)
    shape = (1600, 2400)
    cam = preset("8mp").with_size(shape[1], shape[0])
    pts = grid_points(rng, shape, 4, 3)
    img = render_spots(shape, pts, 0.85, 2e4, SENSOR, rng)
    b = registry.get("cog")(Frame(img, cam), DetectorOptions(coarse_max_px=100_000))
    assert len(b) == len(pts)
    d = np.linalg.norm(b.points_px[None] - pts[:, None], axis=2).min(axis=1)
    assert d.max() < 0.1


def test_a_user_detector_is_one_small_function():
    from deckpose.detect.candidates import measure_candidates

    @registry.register("test-peak")
    def peak(frame, options):
        def measure(c):
            s = c.signal()
            v, u = np.unravel_index(np.argmax(s), s.shape)
            return c.blob(u + c.u0, v + c.v0, flux_dn=float(s.max()))

        return measure_candidates(frame, options, measure)

    rng = np.random.default_rng(9)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    pts = grid_points(rng, SHAPE, 3, 2)
    b = registry.get("test-peak")(
        Frame(render_spots(SHAPE, pts, 1.5, 2e4, SENSOR, rng), cam), DetectorOptions()
    )
    assert isinstance(b, Blobs) and len(b) == 6
    assert "test-peak" in registry.names()
    d = np.linalg.norm(b.points_px[None] - pts[:, None], axis=2).min(axis=1)
    assert d.max() <= 0.75  # the brightest pixel is within half a pixel diagonal
    registry.unregister("test-peak")
    assert "test-peak" not in registry.names()


@pytest.mark.parametrize("name", ["cog", "gauss"])
def test_uneven_background_with_the_opening(name):
    # A lit deck: a brightness ramp (0 -> 1000 e across the frame) and a bright patch
    # (+3000 e, columns 160-319) under the middle column of spots.
    from deckpose.detect.synthetic import add_noise, expected_electrons

    rng = np.random.default_rng(11)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    pts = grid_points(rng, SHAPE, 3, 2)
    ramp = np.linspace(0.0, 1000.0, SHAPE[1])[None, :] + np.zeros(SHAPE)
    ramp[:, 160:320] += 3000.0
    errs = []
    for _ in range(5):
        mu = expected_electrons(SHAPE, pts, 1.5, 3e4, SENSOR.background_e) + ramp
        frame = Frame(add_noise(mu, SENSOR, rng), cam)
        bright_only = registry.get(name)(frame, DetectorOptions(significance_sigma=0))
        # The bright-spot search alone, with one global level, takes the bright patch
        # for a blob (or several) ...
        assert len(bright_only) != 6
        # ... while the opening, or the significance search (each spot against its own
        # surroundings) without it, finds the six spots and nothing else.
        for opts in (DetectorOptions(background_kernel_px=25), DetectorOptions()):
            b = registry.get(name)(frame, opts)
            assert b.ok and len(b) == 6, b.reason
            d = np.linalg.norm(b.points_px[None] - pts[:, None], axis=2)
            errs.append(b.points_px[d.argmin(axis=1)] - pts)
    e = np.concatenate(errs)
    # The border plane removes the gradient: no bias beyond noise (CRB here ~0.02 px).
    assert np.sqrt(np.mean(e**2)) < 0.04
    assert np.all(np.abs(e.mean(axis=0)) < 0.02)


@pytest.mark.parametrize("read_noise_e", [0.0, 0.3])
def test_noise_free_or_quantised_8bit_rgb_has_no_false_blobs(read_noise_e):
    # An 8-bit RGB frame whose background noise is below one DN (or absent, as in a
    # noise-free render): the threshold must not sit one quantum above the background.
    rng = np.random.default_rng(13)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    pts = grid_points(rng, SHAPE, 3, 2)
    sensor = SensorModel(
        gain_dn_per_e=0.02, read_noise_e=read_noise_e, background_e=10.0, bit_depth=8
    )
    img = render_spots(SHAPE, pts, 1.5, 1e5, sensor, rng, rgb=np.ones((6, 3)))
    if read_noise_e == 0.0:  # no noise at all: the expected image, rounded
        from deckpose.detect.synthetic import expected_electrons

        mu = expected_electrons(SHAPE, pts, 1.5, 1e5, 10.0)
        img = np.repeat(np.rint(0.02 * mu).astype(np.uint8)[:, :, None], 3, axis=2)
    for name in ("binary", "cog", "gauss"):
        b = registry.get(name)(Frame(img, cam), DetectorOptions())
        assert len(b) == 6, (name, len(b), b.reason)


@pytest.mark.parametrize(("bit_depth", "sigma_px", "over"), [(12, 1.5, 8.0), (8, 2.5, 10.0)])
def test_gauss_fits_the_wings_of_saturated_spots(bit_depth, sigma_px, over):
    """Cores clipped at full scale (``over`` x the full well at the peak): ``gauss`` is a
    censored fit to the wings, at least as accurate as ``cog``, with a fair covariance.

    12-bit data stored in uint16 also checks that the clip level is found at 4095.
    """
    full_well_e = 15000.0
    sensor = SensorModel(
        gain_dn_per_e=(2**bit_depth - 1) / full_well_e,
        read_noise_e=4.0,
        background_e=100.0,
        bit_depth=bit_depth,
    )
    flux_e = over * full_well_e * 2.0 * np.pi * sigma_px**2
    rng = np.random.default_rng(21 + bit_depth)
    cam = preset("8mp").with_size(SHAPE[1], SHAPE[0])
    frames = []
    for k in range(10):
        pts = grid_points(rng, SHAPE, 4, 3)
        img = render_spots(SHAPE, pts, sigma_px, flux_e, sensor, rng)
        assert (img == 2**bit_depth - 1).sum() >= 12 * 5  # every core clips
        frames.append((Frame(img, cam, k), pts))
    e_gauss, cov, n_det = _errors("gauss", frames)
    e_cog, _, _ = _errors("cog", frames)
    assert n_det == 12 * len(frames)
    rms_gauss = float(np.sqrt(np.mean(e_gauss**2)))
    rms_cog = float(np.sqrt(np.mean(e_cog**2)))
    # measured: gauss 0.0025-0.0032 px, cog 0.006-0.0068 px (120 spots each)
    assert rms_gauss <= rms_cog, (rms_gauss, rms_cog)
    nees = np.einsum("ni,nij,nj->n", e_gauss, np.linalg.inv(cov), e_gauss)
    assert 1.0 < nees.mean() < 3.5, nees.mean()  # chi^2, 2 dof: mean 2


def _housed_spots(rng: np.random.Generator, shape=(240, 320), sigma_px: float = 1.95):
    """Noise-free unclipped spots (peak 30000 DN) in dark elliptical housings (2000 DN,
    semi-axes 13 x 7 px, wider than a 3-sigma window) on a lit, textured deck (6000 +- 300
    DN) crossed by a bright marking (12000 DN) above and below each housing: as rendered
    80 m beacons at dusk look. Returns the uint16 image and the (n, 2) true centres (u, v).
    """
    import cv2

    deck = cv2.GaussianBlur(rng.normal(0.0, 1.0, shape), (0, 0), 1.5)
    img = 6000.0 + 300.0 * deck / deck.std()
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    pts = []
    for v in (60.0, 180.0):
        for u in (60.0, 160.0, 260.0):
            c = (u + rng.uniform(-0.5, 0.5), v + rng.uniform(-0.5, 0.5))
            img[(np.abs(xx - c[0]) <= 3) & (np.abs(yy - c[1]) < 40)] = 12000.0
            img[((xx - c[0]) / 13.0) ** 2 + ((yy - c[1]) / 7.0) ** 2 <= 1.0] = 2000.0
            img += 30000.0 * np.exp(-((xx - c[0]) ** 2 + (yy - c[1]) ** 2) / (2 * sigma_px**2))
            pts.append(c)
    return np.round(img).astype(np.uint16), np.array(pts)


def test_cog_measures_an_unclipped_spot_above_its_housing_floor():
    # The marking raises the spot's pedestal far above the housing, so above the
    # pedestal cog keeps only the top of the core and the deck's texture; above the
    # floor the wings count. The tolerance is the shot-noise CRB of these spots
    # (about 0.0046 px at 4 DN/e): the systematic error alone must stay below it.
    from deckpose.detect.candidates import find_candidates
    from deckpose.detect.centroid import cog_centroid

    err_floor, err_pedestal = [], []
    for seed in range(4):
        img, pts = _housed_spots(np.random.default_rng(seed))
        frame = Frame(img, preset("8mp").with_size(img.shape[1], img.shape[0]))
        cands, reason = find_candidates(frame, DetectorOptions(gain_dn_per_e=4.0))
        assert not reason and len(cands) == len(pts)
        for c in cands:
            for above_floor, errs in ((True, err_floor), (False, err_pedestal)):
                row = cog_centroid(c, above_floor=above_floor)
                errs.append(np.hypot(*(pts - np.array(row[:2])).T).min())
    rms_floor = float(np.sqrt(np.mean(np.square(err_floor))))
    rms_pedestal = float(np.sqrt(np.mean(np.square(err_pedestal))))
    assert rms_floor < 0.0046
    assert rms_floor < 0.5 * rms_pedestal
    # the registered detector is the floor-based one
    img, pts = _housed_spots(np.random.default_rng(9))
    blobs = registry.get("cog")(
        Frame(img, preset("8mp").with_size(img.shape[1], img.shape[0])),
        DetectorOptions(gain_dn_per_e=4.0),
    )
    d = np.hypot(*(blobs.points_px[:, None] - pts[None]).transpose(2, 0, 1)).min(axis=1)
    assert len(d) == len(pts) and d.max() < 0.01


def test_a_dark_heavily_quantised_frame_gives_no_noise_spots():
    # 8-bit RGB whose background is 0.6 DN (median 0): the rare 1-DN pixels are no Gaussian
    # noise, and clusters of them counted as >200 significant spots (the frame failed). A
    # frame whose median is 0 DN gets the bright-spot search alone.
    rng = np.random.default_rng(4)
    cam = preset("8mp").with_size(960, 540)
    pts = grid_points(rng, (540, 960), 4, 3)
    img = render_spots((540, 960), pts, 2.0, 2e5, SENSOR, rng)
    rgb8 = np.repeat(np.clip(img // 32, 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    assert (rgb8[..., 0] == 1).mean() > 0.01  # the rare quanta are there
    for name in ("cog", "gauss"):
        b = registry.get(name)(Frame(rgb8, cam), DetectorOptions())
        assert b.ok and len(b) == len(pts), (name, b.reason, len(b))
