"""Robustness tables: a saved policy evaluated under perturbations of its eval env's params.

A perturbation changes one param (each of several values) or several params together (one combined change).
`evaluate_perturbations` runs, for each perturbed param, every value in one compiled program (the episodes of all
values vmapped together), and all combined changes in one more, beside the nominal params; `table` and `plot`
write what it found. `range_ends` turns a run's randomisation into the single changes that test its edges, and
`worst_corner` those edges' rows into one combined change: every randomised param at its harder edge.
"""

import ast
import numbers
import pathlib
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxarm import envs, ranges
from jaxarm.agents.common.evaluate import evaluate
from jaxarm.envs.randomize import parse_ranges
from jaxarm.runner import plots

TABLE_COLUMNS = ("success_rate", "return_mean")
"""Columns every table row has; the env's final-info means (the sorter's object outcomes) follow them."""


class PerturbationError(ValueError):
    """A perturbation that cannot be evaluated: its text, its param or its value (the message says which)."""


def parse_perturbation(text: str) -> tuple[str, list[float]]:
    """'NAME=V1,V2,...' -> (NAME, [V1, V2, ...]) (numbers, integers where written so); PerturbationError otherwise."""
    name, _, values = text.partition("=")
    try:
        parsed = [ast.literal_eval(value.strip()) for value in values.split(",")]
    except (ValueError, SyntaxError):
        parsed = []
    if not name or not parsed or not all(isinstance(value, numbers.Real) for value in parsed):
        raise PerturbationError(f"a perturbation is NAME=V1,V2,..., got {text!r}")
    return name, parsed


def parse_combined(text: str) -> dict[str, float]:
    """'NAME=V+NAME=V+...' -> {NAME: V, ...}: one change of several params together; PerturbationError
    otherwise."""
    combined = {}
    for part in text.split("+"):
        name, values = parse_perturbation(part)
        if len(values) != 1 or name in combined:
            raise PerturbationError(
                f"a combined perturbation is NAME=V+NAME=V+... (one value each, each name once), got {text!r}"
            )
        combined[name] = values[0]
    return combined


def combined_label(change: Mapping[str, float]) -> str:
    """The table's name of a combined change: 'NAME=V+NAME=V+...'."""
    return "+".join(f"{name}={value:g}" for name, value in change.items())


def range_ends(randomize: Mapping[str, str], env_params) -> dict[str, list[float]]:
    """{param: [low, high]}: each randomised param (`randomize`, as a config holds it) at both ends of its range,
    integer params at the whole numbers they draw."""
    ends = {}
    for name, drawn in parse_ranges(randomize).items():
        low, high = drawn.low, drawn.high
        if np.issubdtype(np.asarray(getattr(env_params, name)).dtype, np.integer):
            low, high = int(np.ceil(low)), int(np.floor(high))
        ends[name] = [low, high]
    return ends


WORST_CORNER = "worst corner"
"""How a table labels the combined change `worst_corner` finds (its params follow, as `combined_label` gives them)."""


def worst_corner(rows: Sequence[dict], ends: Mapping[str, Sequence[float]]) -> dict[str, float]:
    """{param: its harder end}: for each param of `ends` (as `range_ends` gives them), the end whose single-change
    row in `rows` (as `evaluate_perturbations` gives them) succeeded less, the lower return breaking a tie. "Harder"
    is measured, one param at a time with the others nominal, on the same episodes: which end of a range hurts (a
    lighter or a heavier object, more or less friction) depends on the policy, not only on the param."""
    corner = {}
    for name, values in ends.items():
        edge_rows = [row for row in rows if row["param"] == name and row["value"] in values]
        if len(edge_rows) < len(values):
            raise PerturbationError(f"{name}: no row at each end of its range {list(values)}")
        corner[name] = min(edge_rows, key=lambda row: (row["success_rate"], row["return_mean"]))["value"]
    return corner


def check_perturbations(env_params, perturbations: Mapping[str, Sequence[float]]) -> None:
    """PerturbationError for a name that is not an env param, a value outside its declared range, or a param that
    sets the rollout's length (all of a run's rows share one length)."""
    for name, values in perturbations.items():
        if name == "max_episode_steps":
            raise PerturbationError("max_episode_steps sets the rollout's length; evaluate it with eval_env_params")
        for value in values:
            try:
                envs.override_params(env_params, {name: value})
            except KeyError as error:
                raise PerturbationError(error.args[0]) from None
            except ValueError as error:
                raise PerturbationError(str(error)) from None


def evaluate_perturbations(
    env,
    env_params,
    act,
    state,
    key: jax.Array,
    episodes: int,
    perturbations: Mapping[str, Sequence[float]],
    combined: Sequence[Mapping[str, float]] = (),
    with_nominal: bool = True,
) -> list[dict]:
    """Rows {"param", "value", success_rate, return_mean, final_info/...}: the nominal params first ("param"
    "nominal"; left out without `with_nominal`), then each value of each perturbed param with every other param
    nominal, then each `combined` change ("param" its `combined_label`, "value" None). `act(state, obs)` is the
    deterministic policy; every row evaluates the same `episodes` episodes (same key)."""
    batches: list[tuple[str | None, Sequence[Mapping[str, float]]]] = [
        (name, [{name: value} for value in values]) for name, values in perturbations.items()
    ]
    if combined:
        batches.append((None, combined))
    for name, changes in batches:  # each batch's values are evaluated at once, each on `episodes` episodes
        if not ranges.AT_ONCE.admits(len(changes) * episodes):
            raise PerturbationError(
                f"{len(changes):,} {'values of ' + name if name else 'combined changes'} x {episodes:,} episodes "
                f"step {len(changes) * episodes:,} envs at once, more than an evaluation may "
                f"({ranges.AT_ONCE.describe()}); give fewer values or --episodes"
            )
    check_perturbations(env_params, perturbations)
    for change in combined:
        check_perturbations(env_params, {name: [value] for name, value in change.items()})

    def at_values(learner, values: dict[str, jax.Array]):
        params = env_params.replace(**values)
        return evaluate(env, params, lambda obs: act(learner, obs), key, episodes)

    rows = []
    if with_nominal:
        nominal = jax.jit(lambda learner: at_values(learner, {}))
        rows.append({"param": "nominal", "value": None, **nominal(state).summary()})
    for name, changes in batches:
        results = jax.jit(jax.vmap(at_values, in_axes=(None, 0)))(state, _batched_values(env_params, changes))
        for index, change in enumerate(changes):
            result = jax.tree.map(lambda leaf, index=index: leaf[index], results)
            label, value = (name, change[name]) if name else (combined_label(change), None)
            rows.append({"param": label, "value": value, **result.summary()})
    return rows


def _batched_values(env_params, changes: Sequence[Mapping[str, float]]) -> dict[str, jax.Array]:
    """{param: [C] its value in each change, nominal where a change leaves it}, for every param some change sets,
    in the param's dtype; only these are vmapped, the other params stay constants of the program."""
    names = list(dict.fromkeys(name for change in changes for name in change))
    nominal = {name: np.asarray(getattr(env_params, name)) for name in names}
    return {
        name: jnp.asarray([change.get(name, nominal[name]) for change in changes]).astype(nominal[name].dtype)
        for name in names
    }


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
    """Success rate against each perturbed param's value, one panel a param, the nominal success dashed (combined
    changes are in the table alone)."""
    nominal = next(row for row in rows if row["param"] == "nominal")
    names = list(dict.fromkeys(row["param"] for row in rows if row["value"] is not None))
    fig, axes = plots.figure(3.2 * max(len(names), 1), 3.2, columns=max(len(names), 1))
    for ax, name in zip(np.atleast_1d(axes), names, strict=False):
        points = [(row["value"], row["success_rate"]) for row in rows if row["param"] == name]
        ax.plot(*zip(*points, strict=True), marker="o")
        ax.axhline(nominal["success_rate"], color="grey", linestyle="--", label="nominal")
        ax.set_xlabel(name)
        ax.set_ylim(-0.02, 1.02)
    np.atleast_1d(axes)[0].set_ylabel("success rate")
    if names:  # combined changes alone leave the one panel empty, and a legend without lines warns
        np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle(f"{title} ({jax.devices()[0].device_kind})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
