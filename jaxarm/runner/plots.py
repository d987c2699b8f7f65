"""Learning-curve figures drawn without a window.

Figures are made with matplotlib's object API and its Agg canvas, never through pyplot's global backend,
so importing this module changes nothing for notebooks or other plotting code.
"""

import functools
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


def plain_text(draw):
    """`draw`, with every text of its figure drawn as written: names, labels and titles come from the user (a run
    directory's name, --label, --title), and matplotlib took a `$` pair in them for mathtext (`$\\frac$` ended a
    comparison in its 50-line ParseSyntaxException traceback)."""

    @functools.wraps(draw)
    def drawn(*args, **kwargs):
        from matplotlib import rc_context

        with rc_context({"text.parse_math": False}):
            return draw(*args, **kwargs)

    return drawn


def rolling_window(updates: int, at_least: int = 1) -> int:
    """Updates a learning curve's rolling means span: a twentieth of the run's `updates`, at least `at_least`
    (`RunConfig.updates_per_time_limit`: envs whose episodes ran out together, as a run's first episodes and
    those after them do while most fail, finish in bursts one time limit apart, and a window that spans one
    holds each burst with the successes between)."""
    return max(1, at_least, updates // 20)


def rolling_mean(values: np.ndarray, window: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Trailing (weighted) mean over up to `window` values, same length as `values`."""
    weights = np.ones(len(values)) if weights is None else np.asarray(weights, float)

    def trailing_sums(series):
        cumulative = np.cumsum(np.insert(np.asarray(series, float), 0, 0.0))
        ends = np.arange(1, len(cumulative))
        return cumulative[ends] - cumulative[np.maximum(ends - window, 0)]

    return trailing_sums(np.asarray(values, float) * weights) / trailing_sums(weights)


def rolling_rates(rates: np.ndarray, weights: np.ndarray, window: int) -> np.ndarray:
    """[runs, updates]: each run's `rates` [runs, updates] as its `rolling_mean` weighted by its `weights`; NaN
    where a run's window holds no weight."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.stack([rolling_mean(rate, window, weight) for rate, weight in zip(rates, weights, strict=True)])


TRAINING_SUCCESS = "training success (rolling; first episodes count as failures until they end)"
"""How curves label the training episodes' success rate (`jaxarm.agents.common.trainer.summarise_episodes`)."""


def success_weights(rows: list[dict]) -> np.ndarray:
    """[rows] the episodes each row's training success rate is over: its judged episodes (`episodes/judged`), or
    its finished ones in a run logged before those were."""
    return np.array([row.get("episodes/judged", row["episodes/episodes"]) for row in rows], float)


@plain_text
def learning_curve(
    rows: list[dict], path: pathlib.Path, title: str, device: str | None = None, window_at_least: int = 1
) -> None:
    """Two panels over env steps. Above, the success rate: first the evaluations during training (rows with
    "eval/success_rate": the deterministic policy on fresh episodes), then the training episodes' (rolling,
    weighted by the episodes each update judged; `TRAINING_SUCCESS`). Below, the per-update mean episode return
    (scatter), its rolling mean and linear trend. Rolling means span `rolling_window(updates, window_at_least)`.

    Updates in which no episode finished are left out. The device (by default this process's) is named in the
    title.
    """
    evaluations = [row for row in rows if "eval/success_rate" in row]
    rows = [row for row in rows if row.get("episodes/episodes", 0) > 0]
    fig, (success_ax, return_ax) = figure(8, 7, rows=2)
    if evaluations:
        success_ax.plot(
            [row["env_steps"] for row in evaluations],
            [row["eval/success_rate"] for row in evaluations],
            "o-",
            color="C3",
            label="evaluation (fresh episodes, deterministic policy)",
        )
    if rows:
        steps = np.array([row["env_steps"] for row in rows], float)
        returns = np.array([row["episodes/return_mean"] for row in rows])
        success = np.array([row["episodes/success_rate"] for row in rows])
        window = rolling_window(len(rows), window_at_least)
        success_ax.plot(steps, rolling_mean(success, window, success_weights(rows)), color="C2", label=TRAINING_SUCCESS)
        return_ax.scatter(steps, returns, s=6, alpha=0.4, label="training episode return (mean per update)")
        return_ax.plot(steps, rolling_mean(returns, window), color="C0", label="rolling mean")
        if len(rows) > 1:
            slope, intercept = np.polyfit(steps, returns, 1)
            return_ax.plot(steps, slope * steps + intercept, "--", color="gray", label="linear trend")
        return_ax.legend(loc="upper left")
    if evaluations or rows:
        success_ax.legend(loc="lower right", fontsize=8)
    success_ax.set_ylim(-0.02, 1.02)
    success_ax.set_ylabel("success rate")
    success_ax.set_title(f"{title} ({device or jax.devices()[0].device_kind})")
    return_ax.set_xlabel("env steps")
    return_ax.set_ylabel("episode return")
    fig.tight_layout()
    write_figure(fig, path)


def write_figure(fig, path: pathlib.Path) -> None:
    """Writes `fig` to `path` as a PNG; an OSError names `path` (the image writer's own, on its open file, names
    none: a full disk said only "File too large" or "No space left on device")."""
    try:
        fig.savefig(path, dpi=100)
    except OSError as error:
        if error.filename is not None:
            raise
        raise OSError(error.errno, error.strerror, str(path)) from error


@plain_text
def sweep_curves(curves: dict, path: pathlib.Path, title: str) -> None:
    """Mean training success (`TRAINING_SUCCESS`) and episode return over env steps, with 95% CI bands across
    seeds.

    `curves` maps a setting's label to (env_steps, success_rate, return_mean), each [seeds, updates], with
    NaN where a seed has no value (those points are left out of the mean).
    """
    fig, (success_ax, return_ax) = figure(12, 4.5, columns=2)
    for index, (label, (steps, success, returns)) in enumerate(curves.items()):
        x = np.asarray(steps, float)[0]
        for ax, (mean, lower, upper) in ((success_ax, mean_band(success, 0.0, 1.0)), (return_ax, mean_band(returns))):
            ax.plot(x, mean, color=f"C{index}", label=label)
            ax.fill_between(x, lower, upper, color=f"C{index}", alpha=0.2)
    success_ax.set_ylabel(TRAINING_SUCCESS, fontsize=8)
    return_ax.set_ylabel("episode return")
    for ax in (success_ax, return_ax):
        ax.set_xlabel("env steps")
    success_ax.legend(fontsize=7)
    fig.suptitle(f"{title} ({jax.devices()[0].device_kind}); bands: 95% CI over seeds")
    fig.tight_layout()
    write_figure(fig, path)


@plain_text
def run_comparison(curves: dict, path: pathlib.Path, title: str) -> None:
    """Success rate and training return over env steps (left) and over wall clock (right), runs overlaid. The
    success panels draw each run's evaluations during training first (solid, with dots), then its training
    success (dashed, `TRAINING_SUCCESS`).

    `curves` maps a run's label to ((env_steps, wall_seconds, success, returns), (eval_env_steps,
    eval_wall_seconds, eval_success)): the first four [updates], the evaluations' [E] (E may be 0). The title
    names the device.
    """
    fig, axes = figure(12, 8, columns=2, rows=2)
    for index, (label, ((steps, wall, success, returns), (eval_steps, eval_wall, eval_success))) in enumerate(
        curves.items()
    ):
        for column, (x, eval_x) in enumerate(((steps, eval_steps), (wall, eval_wall))):
            axes[0][column].plot(eval_x, eval_success, "o-", color=f"C{index}", markersize=4, label=label)
            axes[0][column].plot(x, success, "--", color=f"C{index}", alpha=0.6)
            axes[1][column].plot(x, returns, color=f"C{index}", label=label)
    for column, xlabel in enumerate(("env steps", "wall clock since the first jit (s)")):
        axes[0][column].set_ylabel("success: evaluations (dots, solid); training (dashed)")
        axes[0][column].set_ylim(-0.02, 1.02)
        axes[1][column].set_ylabel("episode return (training, rolling)")
        axes[1][column].set_xlabel(xlabel)
    axes[1][0].legend(fontsize=8)
    fig.suptitle(f"{title}\ntraining success: {TRAINING_SUCCESS.removeprefix('training success ')}", fontsize=10)
    fig.tight_layout()
    write_figure(fig, path)
