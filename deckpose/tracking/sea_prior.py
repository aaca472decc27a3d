"""The oscillator bank fitted to a sea state: the deck-motion model's spectra from the sea the ship is in.

Roll, pitch and heave of a ship in an irregular sea are the wave spectrum filtered by the
ship's response (:mod:`deckpose.motion`): narrow-band processes whose spectra, in encounter
frequency, follow from the sea state, the wave heading, the ship's speed and its response
amplitudes (:func:`encounter_spectra`). The tracker's model writes each channel as a bank of
damped oscillators driven by white noise (:mod:`deckpose.tracking.deck_motion_model`); its
spectrum is ``sum_k sigma_k^2 s_k(omega)`` with ``s_k`` the unit-variance spectrum of
oscillator ``k`` (:func:`oscillator_density`). :func:`fit_bank_sigmas` chooses the
``sigma_k`` that make the bank's spectrum closest to the sea's in the sense of the Whittle
likelihood (the Gaussian log-likelihood of a spectrum, ``integral log S + I / S``), the measure
that matters to a filter: it weighs each frequency by its log ratio, so the far tail, where
the motion is as weak as the measurement noise and a filter's bandwidth is decided, counts as
much as the peak. A floor of ``floor_rel`` times the sea spectrum's peak stands for the
measurement noise in the fit.

What the filter is told is the sea (as an operator reads it: sea state, heading, speed,
ship), never a realisation of it: the motion a run holds is one random draw from it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError
from deckpose.motion.closed_form import PhaseConvention, response_amplitudes
from deckpose.motion.config import parse_sea_run
from deckpose.motion.irregular import MIN_ENCOUNTER_RAD_S
from deckpose.tracking.deck_motion_model import DeckMotionModel

__all__ = ["SeaPrior", "encounter_spectra", "fit_bank_sigmas", "model_for_sea", "oscillator_density"]

#: Wave-frequency nodes of :func:`encounter_spectra`'s quadrature over the spectrum's band.
_WAVE_NODES = 20_000
#: :func:`model_for_sea` leaves out (sigma 0) an oscillator holding less than this share of its
#: channel's fitted variance: it changes the bank's spectrum by less than the fit's own error
#: and costs two states.
PRUNE_VARIANCE_SHARE = 1e-6


@dataclass(frozen=True)
class SeaPrior:
    """The sea the ship is in, as the tracker is told it (configs: the tracker's ``sea:`` section).

    Attributes
    ----------
    sea_state : int
        Douglas sea state, 1..9 (:mod:`deckpose.motion.spectrum`).
    hs_m, tp_s : float or None
        Significant wave height (m) and peak period (s); None: the state's most probable.
    heading_deg : float
        Wave heading relative to the ship: 180 head seas, 135 bow quartering, 90 beam, 0 following.
    speed_kn : float
        Ship speed, knots.
    ship : str
        Ship preset (:func:`deckpose.motion.ship.ship_preset`).
    spectrum : str
        ``jonswap`` or ``pm``.
    floor_rel : float
        The fit's stand-in for the measurement noise: a white floor of this fraction of the
        sea spectrum's peak density (in (0, 1)); ~1e-5 suits estimates whose noise is that far
        below the motion's peak (sub-pixel detections of a deck tens of metres away).
    keep_variance : tuple of str
        Channels (``roll``, ``pitch``, ``heave``) whose fitted sigmas are scaled so that the
        bank's variance is the sea's. The Whittle fit of a bank whose spectral tails are heavier
        than the sea's keeps only 0.5-0.6 of the sea's sigma (it trades the peak for the tails,
        which is what a filter of measured frames needs); where the measurements say little,
        the filter then claims that too-small sigma. That is the heave (the default): one camera
        measures its height above the deck, and the deck's heave is told from the UAV's own
        climb only by the dynamics, so the filtered heave rate keeps about the model's
        stationary sigma (without the scaling, a rough draw of sea state 6 had heave-rate errors
        of 1.7 of their sigmas and the landing window said go falsely). Roll and pitch are
        measured every frame; their predictions up to 5 s stay conservative without it.
    """

    sea_state: int = 6
    hs_m: float | None = None
    tp_s: float | None = None
    heading_deg: float = 135.0
    speed_kn: float = 15.0
    ship: str = "ffg7"
    spectrum: str = "jonswap"
    floor_rel: float = 1e-5
    keep_variance: tuple[str, ...] = ("heave",)

    def __post_init__(self) -> None:
        if not 0 < self.floor_rel < 1:
            raise ConfigError(f"sea.floor_rel: must lie in (0, 1), got {self.floor_rel:g}")
        bad = [c for c in self.keep_variance if c not in ("roll", "pitch", "heave")]
        if bad:
            raise ConfigError(f"sea.keep_variance: channels are roll, pitch and heave, got {bad}")
        parse_sea_run(self._mapping())  # the motion package's own checks and messages

    def _mapping(self) -> dict[str, object]:
        sea: dict[str, object] = {"sea_state": self.sea_state, "heading_deg": self.heading_deg,
                                  "speed_kn": self.speed_kn, "spectrum": self.spectrum}
        if self.hs_m is not None:
            sea["hs_m"] = self.hs_m
        if self.tp_s is not None:
            sea["tp_s"] = self.tp_s
        return {"ship": self.ship, "sea": sea}


def encounter_spectra(prior: SeaPrior, omega_rad_s: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    """One-sided spectral densities of roll, pitch (rad^2 s/rad) and heave (m^2 s/rad) in encounter frequency.

    ``integral S(omega) d omega`` over ``omega > 0`` is the channel's variance (at the centre of
    gravity). The wave band is integrated on a fine grid and each node's variance
    ``|RAO|^2 S_wave d omega_wave`` is put at its ``|omega_encounter|``, spread linearly between
    the two nearest nodes of ``omega_rad_s``.

    Parameters
    ----------
    prior : SeaPrior
    omega_rad_s : (M,) array of float
        Increasing, evenly spaced encounter frequencies, rad/s.

    Returns
    -------
    dict
        ``roll``, ``pitch``, ``heave``: (M,) arrays of float.
    """
    run = parse_sea_run(prior._mapping())
    sea, ship = run.sea, run.ship
    lo, hi = sea.spectrum.band_rad_s()
    w = np.linspace(lo, hi, _WAVE_NODES)
    dw = w[1] - w[0]
    s_wave = sea.spectrum.density(w) * dw
    r = response_amplitudes(ship, w, heading_rad=sea.heading_rad, speed_m_s=sea.speed_m_s,
                            phase=PhaseConvention.CAUSAL, min_encounter_rad_s=MIN_ENCOUNTER_RAD_S)
    grid = np.asarray(omega_rad_s, float)
    d = grid[1] - grid[0]
    pos = (np.abs(r.omega_encounter_rad_s) - grid[0]) / d
    i0 = np.clip(np.floor(pos).astype(int), 0, grid.size - 2)
    frac = np.clip(pos - i0, 0.0, 1.0)
    out: dict[str, NDArray[np.float64]] = {}
    for name, rao in (("roll", r.roll_rad_per_m), ("pitch", r.pitch_rad_per_m), ("heave", r.heave_m_per_m)):
        var = rao ** 2 * s_wave
        dens = np.zeros(grid.size)
        np.add.at(dens, i0, var * (1.0 - frac) / d)
        np.add.at(dens, i0 + 1, var * frac / d)
        out[name] = dens
    return out


def oscillator_density(omega_rad_s: NDArray[np.float64], omega0_rad_s: NDArray[np.float64],
                       damping_ratio: float) -> NDArray[np.float64]:
    """One-sided spectral densities of unit-variance damped oscillators driven by white noise.

    ``p'' + 2 zeta w0 p' + w0^2 p = w``, white ``w`` of two-sided density ``q = 4 zeta w0^3`` (unit
    variance of ``p``): ``S(omega) = q / ((w0^2 - omega^2)^2 + (2 zeta w0 omega)^2) / pi``, one-sided
    in rad/s (it integrates to 1 over ``omega > 0``).

    Parameters
    ----------
    omega_rad_s : (M,) array of float
    omega0_rad_s : (K,) array of float
        Undamped frequencies.
    damping_ratio : float

    Returns
    -------
    (M, K) array of float
    """
    w = np.asarray(omega_rad_s, float)[:, None]
    w0 = np.asarray(omega0_rad_s, float)[None, :]
    z = float(damping_ratio)
    q = 4.0 * z * w0 ** 3
    return np.asarray(q / ((w0 ** 2 - w ** 2) ** 2 + (2.0 * z * w0 * w) ** 2) / math.pi, dtype=np.float64)


def fit_bank_sigmas(omega_rad_s: NDArray[np.float64], density: NDArray[np.float64], periods_s: tuple[float, ...],
                    damping_ratio: float, floor: float) -> NDArray[np.float64]:
    """Oscillator sigmas whose bank spectrum best matches ``density`` (Whittle likelihood over a white floor).

    Minimises ``sum_j log(B(omega_j) + N) + (density_j + N) / (B(omega_j) + N)`` over
    ``B = sum_k sigma_k^2 s_k`` (:func:`oscillator_density`), ``N = floor``: the expected negative
    log-likelihood of a Gaussian process of spectrum ``density`` measured in white noise ``N``,
    under the bank's spectrum; it is least where the two agree.

    Parameters
    ----------
    omega_rad_s : (M,) array of float
        Evenly spaced frequencies, rad/s.
    density : (M,) array of float
        The target one-sided density on them.
    periods_s : tuple of float
        The bank's undamped periods, seconds.
    damping_ratio : float
    floor : float
        White floor ``N`` (> 0), in the density's unit.

    Returns
    -------
    (K,) array of float
        ``sigma_k``, in the square root of the density's variance unit.
    """
    if not floor > 0:
        raise ValueError(f"floor: must be > 0, got {floor!r}")
    basis = oscillator_density(omega_rad_s, 2.0 * math.pi / np.asarray(periods_s, float), damping_ratio)
    target = np.asarray(density, float) + floor
    total = float(np.sum(density) * (omega_rad_s[1] - omega_rad_s[0]))
    lo = math.log(max(total, floor) * 1e-12)

    def cost(log_var: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        v = np.exp(log_var)
        s = basis @ v + floor
        ratio = target / s
        f = float(np.sum(np.log(s) + ratio))
        grad = (basis.T @ ((1.0 - ratio) / s)) * v
        return f, grad

    x0 = np.full(len(periods_s), math.log(max(total, floor) / len(periods_s)))
    from scipy.optimize import minimize  # here: its import slowed every deckpose command

    res = minimize(cost, x0, jac=True, method="L-BFGS-B", bounds=[(lo, None)] * len(periods_s))
    return np.asarray(np.sqrt(np.exp(res.x)), dtype=np.float64)


def model_for_sea(model: DeckMotionModel, prior: SeaPrior) -> DeckMotionModel:
    """``model`` with its roll, pitch and heave oscillators' sigmas fitted to the sea of ``prior``.

    The bank (periods, damping) is ``model``'s; each channel's per-oscillator sigmas are
    :func:`fit_bank_sigmas` of :func:`encounter_spectra`, on a grid up to four times the
    bank's highest frequency, and the channel sigmas become the fitted bank's. Oscillators
    holding less than :data:`PRUNE_VARIANCE_SHARE` of their channel's variance get sigma 0
    (out of the state).
    """
    w_max = 4.0 * 2.0 * math.pi / min(model.periods_s)
    grid = np.linspace(0.005, w_max, 4000)
    spectra = encounter_spectra(prior, grid)
    fitted: dict[str, tuple[float, ...]] = {}
    for name, scale in (("roll", 180.0 / math.pi), ("pitch", 180.0 / math.pi), ("heave", 1.0)):
        dens = spectra[name]
        sig = fit_bank_sigmas(grid, dens, model.periods_s, model.damping_ratio, prior.floor_rel * float(dens.max()))
        sig[sig ** 2 < PRUNE_VARIANCE_SHARE * float(np.sum(sig ** 2))] = 0.0
        if name in prior.keep_variance:
            sig *= math.sqrt(float(np.sum(dens)) * (grid[1] - grid[0]) / float(np.sum(sig ** 2)))
        fitted[name] = tuple(float(x) for x in sig * scale)
    return dataclasses.replace(
        model, roll_bank_sigmas_deg=fitted["roll"], pitch_bank_sigmas_deg=fitted["pitch"],
        heave_bank_sigmas_m=fitted["heave"],
        roll_sigma_deg=math.hypot(*fitted["roll"]), pitch_sigma_deg=math.hypot(*fitted["pitch"]),
        heave_sigma_m=math.hypot(*fitted["heave"]))
