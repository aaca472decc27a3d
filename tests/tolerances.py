"""One table of float tolerances for the tests, with why each value is what it is."""

#: Round-off of a few float64 matrix products on unit-scale numbers.
ROUNDOFF = 1e-12
#: Pixels: projection of points at ~10-100 m through f ~ 1e3-1e4 px, float64.
PROJECTION_PX = 1e-9
#: Noise-free thesis round trip, degrees. Least-squares conic fits on exact
#: points and the closed-form steps lose a few digits near tilted/level cases.
THESIS_ROUNDTRIP_DEG = 1e-6
#: Noise-free thesis height round trip, units.
THESIS_ROUNDTRIP_HEIGHT = 1e-7
#: Noise-free round trip of the conic/pnp estimators, radians. Exact points; the
#: limits are the iterative undistortion (1e-12 criteria) and the conic's eigen-solve.
ESTIMATOR_ROUNDTRIP_RAD = 1e-7
#: Noise-free round trip of the conic/pnp estimators, metres (heights 20-80 m).
ESTIMATOR_ROUNDTRIP_M = 1e-5
