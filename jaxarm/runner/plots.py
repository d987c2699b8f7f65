"""Learning-curve figures drawn without a window.

Figures are made with matplotlib's object API and its Agg canvas, never through pyplot's global backend,
so importing this module changes nothing for notebooks or other plotting code.
"""

import pathlib

import jax
import numpy as np

from jaxarm.runner.stats import mean_band


def figure(width: float, height: float, columns: int = 1, rows: int = 1):
    # Imported here: matplotlib takes ~0.7 s to import, which an evaluation or a sweep member never draws.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height))
    FigureCanvasAgg(figure)
    return figure, figure.subplots(rows, columns)


def rolling_window(updates: int) -> int:
    """Updates a learning curve's rolling means span: a twentieth of the run's, at least one."""
    return max(1, updates // 20)


def rolling_mean(values: np.ndarray, window: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Trailing (weighted) mean over up to `window` values, same length as `values`."""
    weights = np.ones(len(values)) if weights is None else np.asarray(weights, float)

    def trailing_sums(series):
        cumulative = np.cumsum(np.insert(np.asarray(series, float), 0, 0.0))
        ends = np.arange(1, len(cumulative))
        return cumulative[ends] - cumulative[np.maximum(ends - window, 0)]

    return trailing_sums(np.asarray(values, float) * weights) / trailing_sums(weights)


def learning_curve(rows: list[dict], path: pathlib.Path, title: str, device: str | None = None) -> None:
    """Per-update mean episode return (scatter), its rolling mean and linear trend, and the success rate of
    the training episodes (rolling, weighted by the episodes each update finished).

    Evaluations during training (rows with "eval/success_rate") are drawn as points on the success axis.
    Updates in which no episode finished are left out. The device (by default this process's) is named in
    the title.
    """
    evaluations = [row for row in rows if "eval/success_rate" in row]
    rows = [row for row in rows if row.get("episodes/episodes", 0) > 0]
    fig, ax = figure(8, 4.5)
    if rows:
        steps = np.array([row["env_steps"] for row in rows], float)
        returns = np.array([row["episodes/return_mean"] for row in rows])
        success = np.array([row["episodes/success_rate"] for row in rows])
        episodes = np.array([row["episodes/episodes"] for row in rows])
        window = rolling_window(len(rows))
        ax.scatter(steps, returns, s=6, alpha=0.4, label="episode return (mean per update)")
        ax.plot(steps, rolling_mean(returns, window), color="C0", label="rolling mean")
        if len(rows) > 1:
            slope, intercept = np.polyfit(steps, returns, 1)
            ax.plot(steps, slope * steps + intercept, "--", color="gray", label="linear trend")
        twin = ax.twinx()
        twin.plot(steps, rolling_mean(success, window, episodes), color="C2", label="success rate (rolling)")
        if evaluations:
            twin.plot(
                [row["env_steps"] for row in evaluations],
                [row["eval/success_rate"] for row in evaluations],
                "o-",
                color="C3",
                label="success rate (evaluation)",
            )
        twin.set_ylim(-0.02, 1.02)
        twin.set_ylabel("success rate")
        twin.legend(loc="lower right")
        ax.legend(loc="upper left")
    ax.set_xlabel("env steps")
    ax.set_ylabel("episode return")
    ax.set_title(f"{title} ({device or jax.devices()[0].device_kind})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def sweep_curves(curves: dict, path: pathlib.Path, title: str) -> None:
    """Mean success rate and episode return over env steps, with 95% CI bands across seeds.

    `curves` maps a setting's label to (env_steps, success_rate, return_mean), each [seeds, updates], with
    NaN where a seed finished no episode in that update (those points are left out of the mean).
    """
    fig, (success_ax, return_ax) = figure(12, 4.5, columns=2)
    for index, (label, (steps, success, returns)) in enumerate(curves.items()):
        x = np.asarray(steps, float)[0]
        for ax, (mean, lower, upper) in ((success_ax, mean_band(success, 0.0, 1.0)), (return_ax, mean_band(returns))):
            ax.plot(x, mean, color=f"C{index}", label=label)
            ax.fill_between(x, lower, upper, color=f"C{index}", alpha=0.2)
    success_ax.set_ylabel("success rate (training episodes)")
    return_ax.set_ylabel("episode return")
    for ax in (success_ax, return_ax):
        ax.set_xlabel("env steps")
    success_ax.legend(fontsize=7)
    fig.suptitle(f"{title} ({jax.devices()[0].device_kind}); bands: 95% CI over seeds")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def run_comparison(curves: dict, path: pathlib.Path, title: str) -> None:
    """Training success rate and return over env steps (left) and over wall clock (right), runs overlaid, and
    the evaluations during training as points joined by dashes on the success panels.

    `curves` maps a run's label to ((env_steps, wall_seconds, success, returns), (eval_env_steps,
    eval_wall_seconds, eval_success)): the first four [updates], the evaluations' [E] (E may be 0). The title
    names the device.
    """
    fig, axes = figure(12, 8, columns=2, rows=2)
    for index, (label, ((steps, wall, success, returns), (eval_steps, eval_wall, eval_success))) in enumerate(
        curves.items()
    ):
        for row, values in enumerate((success, returns)):
            for column, x in enumerate((steps, wall)):
                axes[row][column].plot(x, values, color=f"C{index}", label=label)
        for column, x in enumerate((eval_steps, eval_wall)):
            axes[0][column].plot(x, eval_success, "o--", color=f"C{index}", markersize=4)
    for column, xlabel in enumerate(("env steps", "wall clock since the first jit (s)")):
        axes[0][column].set_ylabel("success (line: training, rolling; dots: evaluations)")
        axes[0][column].set_ylim(-0.02, 1.02)
        axes[1][column].set_ylabel("episode return (training, rolling)")
        axes[1][column].set_xlabel(xlabel)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
