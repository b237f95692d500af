"""Fitting a model to a bench log and judging the fit: replays and their residuals, the noise
floor, least squares over a log, refits on held-out runs, the maps' discrepancy, and the
hysteresis views (median line and half-width)."""
