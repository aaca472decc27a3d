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
#: Batched vs single-frame estimates, pose difference in units of the estimate's own
#: sigma. Both stop Levenberg-Marquardt once every step is below 1e-3 sigma
#: (STEP_TOL_SIGMA), and rounding can end them one iteration apart: each is then
#: within about one such step of the optimum, so they agree to 2e-3 sigma.
BATCH_POSE_SIGMA = 2e-3
#: Batched vs single-frame chi-square values (sum of squared whitened residuals):
#: at 2e-3 sigma from the optimum a chi-square differs by (2e-3)^2 = 4e-6.
BATCH_CHI2 = 1e-5
#: Batched vs single-frame effective number of posterior-mean nodes, relative. The nodes sit
#: at up to ~4 sigma from the ML pose, which the two paths agree on to BATCH_POSE_SIGMA: each
#: log-weight moves by up to ~4 x 2e-3, the sum of squared weights by about twice that.
BATCH_POSTERIOR_NODES = 2e-2
#: Batched vs single-frame covariances and everything computed without iterating
#: (closed forms, the thesis estimator, sigmas): relative, a few float64 round-offs
#: amplified by 6x6 inversions and eigen-solves.
BATCH_RELATIVE = 1e-6
