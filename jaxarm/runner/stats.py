"""Confidence intervals over seeds: Student-t bands for curves, a bootstrap interval for a study's table."""

import warnings

import numpy as np


def confidence_halfwidth(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """Half-width of the Student-t 95% CI of the mean over `axis`; NaNs are left out, and where fewer than
    2 values remain the half-width is 0."""
    # Imported here: scipy.stats takes ~1 s to import, which every command that never draws a band would pay.
    from scipy import stats

    values = np.asarray(values, float)
    count = np.sum(~np.isnan(values), axis=axis)
    # Columns with fewer than 2 values get 0 below; numpy warns about them ("Degrees of freedom <= 0").
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanstd(values, axis=axis, ddof=1) / np.sqrt(count)
        half = stats.t.ppf(0.975, np.maximum(count - 1, 1)) * spread
    return np.where(count >= 2, half, 0.0)


def mean_band(
    values: np.ndarray, low: float = -np.inf, high: float = np.inf
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, lower, upper) over axis 0 of `values` [seeds, points], the band the mean's 95% CI clipped to
    [`low`, `high`] (a success rate's band stays in [0, 1]). NaNs are left out; a point with none is NaN, without
    numpy's "Mean of empty slice" warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(np.asarray(values, float), axis=0)
    half = confidence_halfwidth(values)
    return mean, np.clip(mean - half, low, high), np.clip(mean + half, low, high)


def bootstrap_interval(values: np.ndarray, seed: int = 0) -> tuple[float, float]:
    """The percentile bootstrap 95% interval of the mean of `values` [N] (scipy.stats.bootstrap, 10,000
    resamples, a fixed seed so that a table reads the same twice); (v, v) where every value is v."""
    from scipy import stats  # here, as in confidence_halfwidth

    values = np.asarray(values, float)
    if np.ptp(values) == 0:
        return float(values[0]), float(values[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # few distinct values: scipy warns about the resamples
        interval = stats.bootstrap(
            (values,), np.mean, confidence_level=0.95, n_resamples=10_000, method="percentile", random_state=seed
        ).confidence_interval
    return float(interval.low), float(interval.high)
