"""Typed, frozen run configs shared by every learner, their hyper-parameter pytree, and validated overrides.

A config is a frozen dataclass: static choices (sizes, counts, env) are declared with `static(default, range)`;
a field declared with `dynamic(default, range)` is a hyper-parameter `train` takes as data: `hparams()` gathers
those fields into one `HParams` pytree, so seeds × hyper-parameters vmap. Every field's type and declared range
(`jaxarm.ranges`: floats finite, integers within int32) are checked whenever a config is built, so no config
holds a value out of range; `validate()` adds the relations between fields and builds the env with its params,
once a config is made from user input (a preset, overrides, a run directory's config.json). Env constructor
kwargs and env params are (name, value) pairs set on the CLI as `env_kwargs.NAME=VALUE`,
`env_params.NAME=VALUE` and `eval_env_params.NAME=VALUE`; env params are checked against their own ranges.
"""

import ast
import dataclasses
import typing
from collections.abc import Iterable
from typing import Any, TypeVar

import jax
import jax.numpy as jnp

from jaxarm import envs, ranges
from jaxarm.agents.common.teachers import teacher_preset_name
from jaxarm.envs.randomize import Randomized, parse_ranges
from jaxarm.envs.registry import closest_match_hint
from jaxarm.ranges import COUNT, Range

Pairs = tuple[tuple[str, Any], ...]
PAIR_FIELDS = ("env_kwargs", "env_params", "eval_env_params", "randomize")
"""The config fields of (name, value) pairs, each pair set on the CLI as `field.name=value`."""

DYNAMIC = "dynamic"
"""The metadata key `dynamic` sets on a config field."""


def static(default: Any, allowed: Range | None = None) -> Any:
    """Declares a static config field (a size, count or choice fixed at compile time) and its allowed values."""
    return dataclasses.field(default=default, metadata={ranges.RANGE: allowed})


def dynamic(default: float, allowed: Range | None = None) -> float:
    """Declares a config field as a dynamic hyper-parameter, a float `train` takes as data (in `HParams`), and its
    allowed values."""
    return dataclasses.field(default=default, metadata={DYNAMIC: True, ranges.RANGE: allowed})


def inherit(base: type, name: str, default: Any) -> Any:
    """`base`'s field `name` declared again with another default, its range and marks kept."""
    (field,) = [field for field in dataclasses.fields(base) if field.name == name]
    return dataclasses.field(default=default, metadata=field.metadata)


@jax.tree_util.register_pytree_with_keys_class
class HParams:
    """A config's dynamic hyper-parameters by name, e.g. `hparams.gamma`: float32 [] each ([S] under vmap).

    One pytree type serves every learner: its names, the config's dynamic fields, are static structure and its
    values the leaves, so `jax.vmap(train)(keys, hparams)` trains seeds × hyper-parameters at once.
    """

    def __init__(self, **values: Any) -> None:
        self.__dict__.update(values)

    def __getattr__(self, name: str) -> jax.Array:
        # Reached only for names that are not hyper-parameters; declared so that type checkers accept the others.
        raise AttributeError(f"no hyper-parameter {name!r} (there are {', '.join(self.__dict__)})")

    def __setattr__(self, name: str, value: Any) -> None:
        raise dataclasses.FrozenInstanceError(f"cannot assign to {name!r}: HParams is immutable, use replace()")

    def __repr__(self) -> str:
        return f"HParams({', '.join(f'{name}={value!r}' for name, value in self.__dict__.items())})"

    def replace(self, **changes: Any) -> "HParams":
        """A copy with `changes` (name=value) applied; TypeError on a name that is not a hyper-parameter."""
        unknown = set(changes) - set(self.__dict__)
        if unknown:
            raise TypeError(f"no hyper-parameters {sorted(unknown)} (there are {', '.join(self.__dict__)})")
        return HParams(**{**self.__dict__, **changes})

    def tree_flatten_with_keys(self):
        children = [(jax.tree_util.GetAttrKey(name), value) for name, value in self.__dict__.items()]
        return children, tuple(self.__dict__)

    @classmethod
    def tree_unflatten(cls, names: tuple[str, ...], values) -> "HParams":
        return cls(**dict(zip(names, values, strict=True)))


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """Fields every learner's config has.

    Attributes:
      env: registered env name (see `jaxarm.envs.names()`).
      env_kwargs: static env constructor arguments as (name, value) pairs.
      env_params: overrides of the env's default params as (name, value) pairs.
      eval_env_params: further overrides for evaluation only, e.g. switching off a training curriculum.
      randomize: env params drawn afresh per env at every training reset, as (name, range) pairs: "LOW..HIGH"
        uniform, "log:LOW..HIGH" log-uniform, integers over the whole numbers in range (domain randomisation,
        `jaxarm.envs.randomize`). Evaluations run the nominal params; the final one also the randomised ones.
      randomize_corners: fraction of training episodes whose `randomize` params all sit at ends of their ranges
        (each end by a fair coin) instead of being drawn within them: the box's corners, where harder edges
        combine and uniform draws seldom go. 0 draws as before, bit for bit.
      num_envs: envs stepped in parallel.
      total_env_steps: training budget in env steps, rounded up to whole updates and then to whole chunks
        (`num_updates`), so that every chunk is the same compiled program: a shorter last chunk would compile
        again.
      updates_per_chunk: updates compiled into one call; the runner logs and checkpoints between calls. A run
        whose budget needs fewer updates is one chunk of those (`chunk_updates`).
      checkpoint_every_updates: save the learner state at the first chunk end after this many updates.
      eval_episodes: fresh episodes for each deterministic evaluation (during training and at its end).
      eval_every_updates: also evaluate at the first chunk end after each multiple of this many updates,
        logging "eval/..." in metrics and keeping the best-scoring checkpoint; 0 for the final evaluation only.
      seed: PRNG seed of the run.
      init_from: run directory whose latest checkpoint initialises the networks (a warm start, for learners
        that have one, see `jaxarm.agents.registry`; the env maps the old observation onto its own:
        `Env.observation_source_index`); `preset:NAME` to train that preset (with this run's seed) into the run's
        warm_start/ first, in the same command; "" for none.
      retry_below: success rate the in-training evaluations (`eval_every_updates`) must have reached by
        `retry_at_env_steps`; a try whose best evaluation is below it at the first evaluation from there on is set
        aside (its files under `tries/K/` of the run directory) and the run starts again from its beginning (its warm
        start, where it has one) with fresh randomness, up to `tries` tries in all, the last trained to the end
        whatever it scores: for recipes that fail on some draws and show it early. 0 for never.
      retry_at_env_steps: the env steps by which a try must reach `retry_below`.
      retry_train_below: an earlier gate of the same tries, on the training episodes (no evaluation, and what a
        try that will learn shows first): the share of them that succeeded over the last time limit of updates up
        to `retry_train_at_env_steps` (`episodes/success_rate` weighted by `episodes/judged`) must reach it, or the
        try is set aside as at `retry_below`. 0 for none.
      retry_train_at_env_steps: the env steps at whose first chunk end `retry_train_below` is applied.
      tries: the most tries a run makes under `retry_below`, the first included (without a gate, one).
      retry_warm_start: with a gate and a warm start named by preset (`init_from=preset:NAME`), a try that fails the
        gate sets its warm start aside too (`tries/K/warm_start/`), and the next try trains that preset again first,
        with a seed of its own (`jaxarm.runner.tries.warm_start_seed`): for recipes whose first stage, more than
        the try's own randomness, decides whether a try learns.
    """

    env: str = "arm2d"
    env_kwargs: Pairs = ()
    env_params: Pairs = ()
    eval_env_params: Pairs = ()
    randomize: Pairs = ()
    randomize_corners: float = static(0.0, ranges.UNIT_INTERVAL)
    num_envs: int = static(256, ranges.AT_ONCE)
    total_env_steps: int = static(1_000_000, ranges.HOST_COUNT)
    updates_per_chunk: int = static(10, ranges.UPDATES_AT_ONCE)
    checkpoint_every_updates: int = static(50, COUNT)
    eval_episodes: int = static(1000, ranges.AT_ONCE)
    seed: int = static(0, ranges.SEED)
    init_from: str = ""
    eval_every_updates: int = static(0, ranges.NON_NEGATIVE)
    retry_below: float = static(0.0, ranges.UNIT_INTERVAL)
    retry_at_env_steps: int = static(0, ranges.NON_NEGATIVE)
    retry_train_below: float = static(0.0, ranges.UNIT_INTERVAL)
    retry_train_at_env_steps: int = static(0, ranges.NON_NEGATIVE)
    tries: int = static(1, ranges.TRIES)
    retry_warm_start: bool = False

    @property
    def budget_shapes_updates(self) -> str:
        """What in the learner's updates follows `total_env_steps` (e.g. a learning-rate schedule), "" if nothing:
        such a run's budget cannot change on resume. Learners' configs say so where it applies."""
        return ""

    def __post_init__(self) -> None:
        ranges.check_fields(self)

    @property
    def env_steps_per_update(self) -> int:
        """Env steps one update collects (each learner's config defines it)."""
        raise NotImplementedError(f"{type(self).__name__} does not define env_steps_per_update")

    @property
    def chunk_updates(self) -> int:
        """Updates per compiled chunk: `updates_per_chunk`, or the updates the whole budget needs if fewer."""
        return min(self.updates_per_chunk, -(-self.total_env_steps // self.env_steps_per_update))

    @property
    def num_updates(self) -> int:
        """Updates in the run: `total_env_steps` rounded up to whole chunks of `chunk_updates`. A run overshoots
        its budget by less than one chunk, and a chunk is never longer than the whole budget needs."""
        chunk_steps = self.env_steps_per_update * self.chunk_updates
        return -(-self.total_env_steps // chunk_steps) * self.chunk_updates

    def updates_per_time_limit(self) -> int:
        """Updates in which every env runs at least its time limit (`max_episode_steps`) of steps; builds the env."""
        time_limit = int(self.make_env(randomized=False)[1].max_episode_steps)
        return -(-time_limit * self.num_envs // self.env_steps_per_update)

    @classmethod
    def dynamic_fields(cls) -> tuple[str, ...]:
        """Names of the fields declared with `dynamic(...)`, in declaration order."""
        return tuple(field.name for field in dataclasses.fields(cls) if field.metadata.get(DYNAMIC, False))

    def hparams(self) -> HParams:
        """The dynamic fields as float32 scalars: the argument `train` takes, and vmaps over in sweeps."""
        return HParams(**{name: jnp.asarray(getattr(self, name), jnp.float32) for name in self.dynamic_fields()})

    def validate(self) -> None:
        """Raises ValueError on a config no run can use: fields that do not fit together (each relation is stated
        here, or in a learner's config, which extends this after `super().validate()`), an unknown env or env
        kwarg, or env params out of their ranges. Each field's own range was checked when the config was built.
        """
        if self.env_steps_per_update > ranges.INT32.max:
            raise ValueError(
                f"an update collects {self.env_steps_per_update:,} env steps (num_envs={self.num_envs:,} x its "
                f"steps per env), more than the learners' int32 step counters hold ({ranges.INT32.max:,})"
            )
        if self.num_updates > ranges.INT32.max:
            raise ValueError(
                f"total_env_steps={self.total_env_steps:,} needs {self.num_updates:,} updates, more than the learners' "
                f"int32 update counter holds ({ranges.INT32.max:,}): collect more env steps per update"
            )
        self._validate_retries()
        if self.randomize_corners > 0 and not self.randomize:
            raise ValueError(f"randomize_corners={self.randomize_corners:g} needs randomize.NAME=LOW..HIGH ranges")
        try:
            self.make_eval_env(randomized=True)
        except (KeyError, ValueError, TypeError) as error:
            raise ValueError(error.args[0] if error.args else str(error)) from None

    def _validate_retries(self) -> None:
        """ValueError where `retry_below`, `retry_at_env_steps`, `retry_train_below`, `retry_train_at_env_steps`,
        `tries` and `retry_warm_start` do not make gates a run can apply."""
        if self.retry_warm_start and not (self.retry_below and teacher_preset_name(self.init_from) is not None):
            raise ValueError(
                "retry_warm_start=true trains a warm start again after a try fails its gate: it needs a gate "
                f"(retry_below=P, got {self.retry_below:g}) and a warm start named by preset (init_from=preset:NAME, "
                f"got {self.init_from!r})"
            )
        if self.retry_train_below and not self.retry_below:
            raise ValueError(
                f"retry_train_below={self.retry_train_below:g} is an earlier gate of retry_below's tries: it needs "
                "retry_below=P as well (retry_below=0 switches the gates off)"
            )
        if not self.retry_below:
            return
        if self.retry_train_below and not 0 < self.retry_train_at_env_steps < self.retry_at_env_steps:
            raise ValueError(
                f"retry_train_at_env_steps={self.retry_train_at_env_steps:,} must lie after the run's start and "
                f"before retry_at_env_steps={self.retry_at_env_steps:,} (retry_train_below=0 switches that gate off)"
            )
        if self.tries < 2:
            raise ValueError(f"retry_below={self.retry_below:g} needs tries=N of at least 2 (the first included)")
        if not self.eval_every_updates:
            raise ValueError(f"retry_below={self.retry_below:g} needs eval_every_updates=N: the evaluations it reads")
        if not 0 < self.retry_at_env_steps < self.num_updates * self.env_steps_per_update:
            raise ValueError(
                f"retry_at_env_steps={self.retry_at_env_steps:,} must lie inside the run's "
                f"{self.num_updates * self.env_steps_per_update:,} env steps, after its start (retry_below=0 "
                "switches the gate off)"
            )

    def make_env(self, randomized: bool = True):
        """Returns (env, env_params) described by this config: what training runs on, with the `randomize` params
        drawn at every reset (`randomized=False`: the nominal env)."""
        env = envs.make(self.env, **dict(self.env_kwargs))
        params = envs.override_params(env.default_params(), dict(self.env_params), prefix="env_params.")
        if randomized and self.randomize:
            env = Randomized(env, parse_ranges(dict(self.randomize)), self.randomize_corners)
        return env, params

    def make_eval_env(self, randomized: bool = False):
        """Returns (env, env_params) that evaluations run on: the nominal training env (`randomized`: with the
        `randomize` params drawn per episode) with `eval_env_params` applied."""
        env, env_params = self.make_env(randomized)
        return env, envs.override_params(env_params, dict(self.eval_env_params), prefix="eval_env_params.")


def parse_number(text: str, expected: str) -> float:
    """`text` as a float; ValueError saying what was `expected` ("an integer") for anything else, where float's
    own error ("could not convert string to float") names neither the field's type nor its syntax."""
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"expected {expected}, got {text!r}") from None


def parse_value(text: str, annotation) -> Any:
    """Parses a CLI string into `annotation` (int, float, bool, str, tuple[int, ...]); ValueError otherwise."""
    if annotation is bool:
        if text.lower() in ("true", "1", "yes"):
            return True
        if text.lower() in ("false", "0", "no"):
            return False
        raise ValueError(f"expected true/false, got {text!r}")
    if annotation is int:
        # Through float, so that 1e6 and 1_000_000.0 count as the integers they are.
        number = parse_number(text, "an integer")
        if not number.is_integer():
            raise ValueError(f"expected an integer, got {text!r}")
        return int(number)
    if annotation is float:
        return parse_number(text, "a number")
    if annotation is str:
        return text
    if typing.get_origin(annotation) is tuple:
        item_type = typing.get_args(annotation)[0]
        # `64,64`, `[64,64]` and `(64, 64)` all name the same sizes.
        parts = text.strip().removeprefix("[").removeprefix("(").removesuffix("]").removesuffix(")").split(",")
        return tuple(parse_value(part.strip(), item_type) for part in parts if part.strip())
    raise ValueError(f"cannot parse a value of type {annotation}")


def parse_literal(text: str) -> Any:
    """Parses an env param or kwarg value: a Python literal (number, list, bool; true and false too, as the
    config's own bool fields take them) or else the string."""
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def with_pair(pairs: Pairs, name: str, value: Any) -> Pairs:
    return tuple((key, val) for key, val in pairs if key != name) + ((name, value),)


def with_pairs(pairs: Pairs, changes: Pairs) -> Pairs:
    """`pairs` with each (name, value) of `changes` set in turn (`with_pair`)."""
    for name, value in changes:
        pairs = with_pair(pairs, name, value)
    return pairs


AnyConfig = TypeVar("AnyConfig", bound=RunConfig)


def apply_overrides(config: AnyConfig, overrides: Iterable[str], validate: bool = True) -> AnyConfig:
    """Returns `config` with `key=value` overrides applied, each parsed to its field's type, then validated
    (`validate=False` leaves out `config.validate()`, which builds the env and with it starts JAX's backend).

    Raises ValueError with a one-line message (naming the closest key for a typo) on any bad override.
    """
    hints = typing.get_type_hints(type(config))
    fields = {field.name for field in dataclasses.fields(config)}
    for item in overrides:
        if "=" not in item or item.startswith("="):
            raise ValueError(f"override {item!r} is not of the form key=value")
        key, text = item.split("=", 1)
        group, _, name = key.partition(".")
        if name and group in PAIR_FIELDS:
            value = text if group == "randomize" else parse_literal(text)  # ranges stay text: "0.8..3.0"
            pairs: dict[str, Any] = {group: with_pair(getattr(config, group), name, value)}
            config = dataclasses.replace(config, **pairs)
            continue
        if key not in fields:
            raise ValueError(f"unknown config key {key!r}{closest_match_hint(key, fields)}")
        try:
            value = parse_value(text, hints[key])
        except ValueError as error:
            raise ValueError(f"bad value for {key}: {error}") from None
        config = dataclasses.replace(config, **{key: value})
    if validate:
        config.validate()
    return config
