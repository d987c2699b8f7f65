"""Robustness tables: a saved policy evaluated under single perturbations of its eval env's params.

`evaluate_perturbations` runs, for each perturbed param, every value in one compiled program (the episodes of all
values vmapped together), beside the nominal params; `table` and `plot` write what it found.
"""

import ast
import numbers
import pathlib
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import envs
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.runner import plots

TABLE_COLUMNS = ("success_rate", "return_mean")
"""Columns every table row has; the env's final-info means (the sorter's object outcomes) follow them."""


def parse_perturbation(text: str) -> tuple[str, list[float]]:
    """'NAME=V1,V2,...' -> (NAME, [V1, V2, ...]) (numbers, integers where written so); ValueError otherwise."""
    name, _, values = text.partition("=")
    try:
        parsed = [ast.literal_eval(value.strip()) for value in values.split(",")]
    except (ValueError, SyntaxError):
        parsed = []
    if not name or not parsed or not all(isinstance(value, numbers.Real) for value in parsed):
        raise ValueError(f"--perturb takes NAME=V1,V2,..., got {text!r}")
    return name, parsed


def check_perturbations(env_params, perturbations: Mapping[str, Sequence[float]]) -> None:
    """ValueError for a name that is not an env param, a value outside its declared range, or a param that sets
    the rollout's length (all of a run's rows share one length)."""
    for name, values in perturbations.items():
        if name == "max_episode_steps":
            raise ValueError("--perturb: max_episode_steps sets the rollout's length; evaluate it with eval_env_params")
        for value in values:
            try:
                envs.override_params(env_params, {name: value}, prefix="--perturb ")
            except KeyError as error:
                raise ValueError(error.args[0]) from None


def evaluate_perturbations(
    env, env_params, act, state, key: jax.Array, episodes: int, perturbations: Mapping[str, Sequence[float]]
) -> list[dict]:
    """Rows {"param", "value", success_rate, return_mean, final_info/...}: the nominal params first ("param"
    "nominal"), then each value of each perturbed param with every other param nominal. `act(state, obs)` is the
    deterministic policy; every row evaluates the same `episodes` episodes (same key)."""
    check_perturbations(env_params, perturbations)
    nominal = jax.jit(lambda learner: evaluate(env, env_params, lambda obs: act(learner, obs), key, episodes))
    rows = [{"param": "nominal", "value": None, **nominal(state).summary()}]
    for name, values in perturbations.items():
        dtype = jnp.asarray(getattr(env_params, name)).dtype
        batch = jnp.asarray(values).astype(dtype)

        def at_value(learner, value, name=name):
            params = env_params.replace(**{name: value})
            return evaluate(env, params, lambda obs: act(learner, obs), key, episodes)

        results = jax.jit(jax.vmap(at_value, in_axes=(None, 0)))(state, batch)
        for index, value in enumerate(values):
            result = jax.tree.map(lambda leaf, index=index: leaf[index], results)
            rows.append({"param": name, "value": value, **result.summary()})
    return rows


def table(rows: Sequence[dict]) -> str:
    """The rows as a markdown table: param, value, success, return, then the env's final-info means."""
    info = sorted({column for row in rows for column in row if column.startswith("final_info/")})
    columns = [*TABLE_COLUMNS, *info]
    header = "| param | value | " + " | ".join(name.removeprefix("final_info/") for name in columns) + " |"
    lines = [header, "|---|---:|" + "---:|" * len(columns)]
    for row in rows:
        value = "" if row["value"] is None else f"{row['value']:g}"
        cells = " | ".join(f"{row.get(column, float('nan')):.3f}" for column in columns)
        lines.append(f"| {row['param']} | {value} | {cells} |")
    return "\n".join(lines)


def plot(rows: Sequence[dict], path: pathlib.Path, title: str) -> None:
    """Success rate against each perturbed param's value, one panel a param, the nominal success dashed."""
    nominal = next(row for row in rows if row["param"] == "nominal")
    names = list(dict.fromkeys(row["param"] for row in rows if row["param"] != "nominal"))
    fig, axes = plots.figure(3.2 * max(len(names), 1), 3.2, columns=max(len(names), 1))
    for ax, name in zip(np.atleast_1d(axes), names, strict=False):
        points = [(row["value"], row["success_rate"]) for row in rows if row["param"] == name]
        ax.plot(*zip(*points, strict=True), marker="o")
        ax.axhline(nominal["success_rate"], color="grey", linestyle="--", label="nominal")
        ax.set_xlabel(name)
        ax.set_ylim(-0.02, 1.02)
    np.atleast_1d(axes)[0].set_ylabel("success rate")
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle(f"{title} ({jax.devices()[0].device_kind})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
