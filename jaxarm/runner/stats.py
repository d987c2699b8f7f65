"""Confidence intervals over seeds."""

import numpy as np
from scipy import stats


def confidence_halfwidth(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """Half-width of the Student-t 95% CI of the mean over `axis`; NaNs are left out, and where fewer than
    2 values remain the half-width is 0."""
    values = np.asarray(values, float)
    count = np.sum(~np.isnan(values), axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        spread = np.nanstd(values, axis=axis, ddof=1) / np.sqrt(count)
        half = stats.t.ppf(0.975, np.maximum(count - 1, 1)) * spread
    return np.where(count >= 2, half, 0.0)
