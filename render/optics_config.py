"""The ``optics:`` section of a render config: the lens beyond a Gaussian."""

from __future__ import annotations

from dataclasses import dataclass

from deckpose.errors import ConfigError
from deckpose.typed_config import check_range, from_mapping

__all__ = ["OpticsSpec", "optics_spec"]


@dataclass(frozen=True)
class OpticsSpec:
    """The lens beyond a Gaussian (:mod:`deckpose.render.optics`), applied to the light spots.

    Each effect is off by default and switched on alone: ``focus_distance_m`` (null: no
    defocus) with ``f_number`` gives each spot a uniform blur disc of the thin-lens
    diameter at its distance; ``diffraction`` convolves it with the Airy pattern of
    ``f_number`` at ``wavelength_nm`` (red, green, blue) for pixels of ``pixel_pitch_um``;
    ``glare_fraction`` of the light goes into a wide point-symmetric tail
    (``(1 + (r / glare_radius_px)**2)**-1.5``) and ``spike_fraction`` into diffraction
    spikes of an aperture of ``spike_blades`` blades (``spike_length_px`` their 1/e
    length); ``bloom`` spills the charge above the full well along columns;
    ``vignetting_exponent`` ``n`` dims the raster and the spots by ``cos(theta)**n``
    (4: the cos^4 law); ``lateral_ca_ppm`` ``[red, blue]`` is each channel's radial
    magnification relative to green minus one, parts per million; ``field_blur_px``
    is the sigma of an extra Gaussian blur at the image corner, growing with the square
    of the distance from the principal point.
    """

    f_number: float = 2.8
    focus_distance_m: float | None = None
    pixel_pitch_um: float = 2.0
    diffraction: bool = False
    wavelength_nm: tuple[float, float, float] = (610.0, 540.0, 465.0)
    glare_fraction: float = 0.0
    glare_radius_px: float = 3.0
    spike_blades: int = 6
    spike_fraction: float = 0.0
    spike_length_px: float = 8.0
    bloom: bool = False
    vignetting_exponent: float = 0.0
    lateral_ca_ppm: tuple[float, float] = (0.0, 0.0)
    field_blur_px: float = 0.0

    def enabled(self) -> bool:
        """Whether any effect is on (off: the spots and frames are today's, bit for bit)."""
        return (self.focus_distance_m is not None or self.diffraction or self.glare_fraction > 0
                or self.spike_fraction > 0 or self.bloom or self.vignetting_exponent > 0
                or any(c != 0 for c in self.lateral_ca_ppm) or self.field_blur_px > 0)


def optics_spec(doc: object, where: str = "optics") -> OpticsSpec:
    spec = from_mapping(OpticsSpec, doc, where)
    check_range(spec.f_number, f"{where}.f_number", low=0.5, high=64)
    if spec.focus_distance_m is not None:
        check_range(spec.focus_distance_m, f"{where}.focus_distance_m", low=0, low_open=True)
    check_range(spec.pixel_pitch_um, f"{where}.pixel_pitch_um", low=0.3, high=30)
    for i, w in enumerate(spec.wavelength_nm):
        check_range(w, f"{where}.wavelength_nm[{i}]", low=300, high=1100)
    check_range(spec.glare_fraction, f"{where}.glare_fraction", low=0, high=1, high_open=True)
    check_range(spec.spike_fraction, f"{where}.spike_fraction", low=0, high=1, high_open=True)
    if spec.glare_fraction + spec.spike_fraction >= 1:
        raise ConfigError(f"{where}: glare_fraction + spike_fraction must be < 1 (the rest is the core), "
                          f"got {spec.glare_fraction + spec.spike_fraction:g}")
    check_range(spec.glare_radius_px, f"{where}.glare_radius_px", low=0.5, high=50)
    check_range(spec.spike_blades, f"{where}.spike_blades", low=3, high=24)
    check_range(spec.spike_length_px, f"{where}.spike_length_px", low=1, high=100)
    check_range(spec.vignetting_exponent, f"{where}.vignetting_exponent", low=0, high=8)
    for name, ppm in zip(("red", "blue"), spec.lateral_ca_ppm):
        check_range(ppm, f"{where}.lateral_ca_ppm ({name})", low=-10000, high=10000)
    check_range(spec.field_blur_px, f"{where}.field_blur_px", low=0, high=20)
    return spec
