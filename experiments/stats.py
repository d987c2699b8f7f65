"""Confidence intervals over seeds."""

import numpy as np
from scipy import stats


def confidence_halfwidth(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """Half-width of the Student-t 95% CI of the mean over `axis` (zeros with fewer than 2 values)."""
    values = np.asarray(values, float)
    count = values.shape[axis]
    if count < 2:
        return np.zeros(np.delete(values.shape, axis))
    return stats.t.ppf(0.975, count - 1) * values.std(axis=axis, ddof=1) / np.sqrt(count)
