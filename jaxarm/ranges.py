"""Allowed values of config fields and env params, declared beside each field, and the checks that enforce them.

A field states its range once, beside its default, in its dataclass metadata (`Range` under the key `RANGE`): run
configs through `static(...)` and `dynamic(...)` (jaxarm.agents.common.config), env params through `ranged(...)`.
The checks here are generic: beyond each field's declared range, every float must be finite and every integer must
fit in int32 (the dtype of jaxarm's update counters, indices and int params), or in int64 where the range says the
count lives on the host alone (`Range.host_count`: a budget in env steps). Messages name the field and what it must
be, in one line. Nothing here runs inside jit: params made inside a compiled program are not checked, and the envs
clean up what such params break (see jaxarm.envs.base).
"""

import dataclasses
import math
import numbers
import typing
from collections.abc import Iterable
from typing import Any

import jax.numpy as jnp
import numpy as np

RANGE = "range"
"""The metadata key under which a field declares its `Range`."""

INT32 = np.iinfo(np.int32)
INT64 = np.iinfo(np.int64)


@dataclasses.dataclass(frozen=True)
class Range:
    """The values a number (or each element of an array) may take, or the strings a choice may take.

    Attributes:
      gt, ge: exclusive and inclusive lower bounds (None: none).
      lt, le: exclusive and inclusive upper bounds (None: none).
      choices: the allowed values of a choice (strings, or an int param's codes); empty for a numeric range.
      host_count: an integer that only the host holds (never a device array), so it may use all of int64.
    """

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple[Any, ...] = ()
    host_count: bool = False

    def admits(self, value: Any) -> bool:
        """Whether `value` (a scalar, or every element of an array) lies in the range."""
        if self.choices:
            return value in self.choices if isinstance(value, str) else bool(np.all(np.isin(value, self.choices)))
        array = np.asarray(value)
        below = (self.gt is not None and np.any(array <= self.gt)) or (self.ge is not None and np.any(array < self.ge))
        above = (self.lt is not None and np.any(array >= self.lt)) or (self.le is not None and np.any(array > self.le))
        return not (below or above)

    def describe(self) -> str:
        """The range in words: 'one of a, b', '> 0', '>= 1', 'in (0, 1]'."""
        if self.choices:
            return "one of " + ", ".join(str(choice) for choice in self.choices)
        low = f"({_bound(self.gt)}" if self.gt is not None else f"[{_bound(self.ge)}" if self.ge is not None else None
        high = f"{_bound(self.lt)})" if self.lt is not None else f"{_bound(self.le)}]" if self.le is not None else None
        if low and high:
            return f"in {low}, {high}"
        if low:
            return f"{'>' if self.gt is not None else '>='} {low[1:]}"
        if high:
            return f"{'<' if self.lt is not None else '<='} {high[:-1]}"
        return "any value"


def _bound(value: float) -> str:
    """A bound in words: an integer in full (1048576, not 1.04858e+06), a float in `g` format."""
    return str(value) if isinstance(value, int) else f"{value:g}"


POSITIVE = Range(gt=0)
NON_NEGATIVE = Range(ge=0)
COUNT = Range(ge=1)
"""An integer count or size of at least one."""
AT_ONCE = Range(ge=1, le=1 << 20)
"""A count of envs or episodes stepped at once in one program (a run's `num_envs`, an evaluation's episodes), or of
samples drawn at once (a replay batch): at most 128 times the largest preset's 8192 envs, checked before anything is
allocated (`num_envs=1e7` and `--episodes 1e8` ran out of memory with a traceback)."""
LAYER_WIDTH = Range(ge=1, le=1 << 16)
"""Units of one network layer, or an encoder's features: at most 65,536, 64 times the widest preset's 1,024, checked
before a network is made (two layers of 1e8 units asked XLA for 40 PB and ended in its out-of-memory traceback)."""
UPDATES_AT_ONCE = Range(ge=1, le=1 << 20)
"""Updates compiled into one call (a run's `updates_per_chunk`): at most 1,048,576, ~200 times the largest preset's
5,000, checked before the chunk is compiled (a chunk keeps each update's metrics: 6e8 updates in one chunk grew past
24 GB until the memory limit killed the run)."""
PASSES = Range(ge=1, le=1 << 12)
"""Passes over one update's data, or gradient steps in one update (PPO's `num_epochs`, TD3's
`grad_steps_per_update`): at most 4,096, 512 times the presets' largest 8, checked before the update is compiled
(an update keeps each pass's metrics: num_epochs=1e9 asked XLA for 136 GB and ended in its out-of-memory
traceback)."""
REPLAY_SIZE = Range(ge=1, le=1 << 26)
"""Transitions a replay buffer holds: at most 67,108,864, 16 times the largest preset's 4e6, checked before the
buffer is allocated at the start of training."""
TRIES = Range(ge=1, le=16)
"""Tries of a run that starts again when it fails its gate (`RunConfig.tries`): each is a whole training, so a
handful; 16 bounds what a typo could cost."""
SEED = NON_NEGATIVE
"""A PRNG seed: a run's (`RunConfig.seed`), and the `--seed` of the commands that draw episodes for one (an
evaluation, a transfer, a rehearsal)."""
HOST_COUNT = Range(ge=1, host_count=True)
"""A count of at least one kept on the host alone (env steps of a budget), up to int64's maximum."""
UNIT_INTERVAL = Range(ge=0, le=1)
DISCOUNT = Range(gt=0, le=1)
LEARNING_RATE = Range(gt=0, le=1)
"""An optimiser's step size: past 1 an Adam update moves every weight by about that much, and learning fails."""


def ranged(default: Any = dataclasses.MISSING, allowed: Range | None = None) -> Any:
    """An env params field defaulting to `default` (a number or nested list of numbers: int32 for integers, else
    float32; none: the env supplies the value, as one shaped by its constructor) whose values must be finite and
    lie in `allowed` (None: any)."""
    metadata = {RANGE: allowed}
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata=metadata)
    dtype = jnp.int32 if np.asarray(default).dtype.kind == "i" else jnp.float32
    return dataclasses.field(default_factory=lambda: jnp.asarray(default, dtype), metadata=metadata)


def declared_range(field: dataclasses.Field) -> Range | None:
    """The range `field` declares, None where it declares none (finite, int32-sized values still apply)."""
    return field.metadata.get(RANGE)


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _check_number(name: str, value: Any, integer: bool, allowed: Range | None) -> None:
    """The generic checks of one number (finite float, int32-sized integer), then its declared range."""
    if integer:
        if not _is_int(value):
            raise ValueError(f"{name} must be an integer, got {value!r}")
        bits = INT64 if allowed is not None and allowed.host_count else INT32
        if not bits.min <= value <= bits.max:
            raise ValueError(f"{name} must fit in {bits.dtype} (at most {bits.max:,} in magnitude), got {value:,}")
    else:
        if not _is_number(value):
            raise ValueError(f"{name} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value}")
    if allowed is not None and not allowed.admits(value):
        raise ValueError(f"{name} must be {allowed.describe()}, got {value}")


def check_value(name: str, value: Any, annotation: Any, allowed: Range | None) -> None:
    """Raises ValueError naming `name` unless `value` is of type `annotation` (int, float, bool, str, or a tuple
    of those, including the (name, value) pairs of env settings) and lies in `allowed` (element-wise for tuples)."""
    if annotation is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{name} must be true or false, got {value!r}")
    elif annotation is int or annotation is float:
        _check_number(name, value, annotation is int, allowed)
    elif annotation is str:
        if not isinstance(value, str):
            raise ValueError(f"{name} must be a string, got {value!r}")
        if allowed is not None and not allowed.admits(value):
            raise ValueError(f"{name} must be {allowed.describe()}, got {value!r}")
    elif typing.get_origin(annotation) is tuple:
        args = typing.get_args(annotation)
        variadic = len(args) == 2 and args[1] is Ellipsis
        if not isinstance(value, tuple) or not (variadic or len(value) == len(args)):
            raise ValueError(f"{name} must be a tuple of {'any length' if variadic else len(args)}, got {value!r}")
        for index, item in enumerate(value):
            check_value(f"{name}[{index}]", item, args[0] if variadic else args[index], allowed)
    elif annotation is Any:
        pass
    else:
        raise TypeError(f"no check for {name}'s type {annotation}")


def check_fields(instance: Any) -> None:
    """Checks every field of a dataclass instance of plain Python values against its type and declared range."""
    hints = typing.get_type_hints(type(instance))
    for field in dataclasses.fields(instance):
        check_value(field.name, getattr(instance, field.name), hints[field.name], declared_range(field))


def param_array(name: str, value: Any, like: np.ndarray) -> np.ndarray:
    """`value` as an array of `like`'s dtype; ValueError naming `name` for a non-number, a non-integer or an int32
    overflow where `like` holds integers, and NaN, inf or a magnitude beyond the dtype's largest where it holds
    floats. Shapes are the caller's to check."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or an array of numbers, got {value!r}") from None
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {value}")
    if np.issubdtype(like.dtype, np.floating):
        largest = float(np.finfo(like.dtype).max)
        if np.any(np.abs(array) > largest):  # it would become inf
            raise ValueError(f"{name} must fit in {like.dtype} (at most {largest:g} in magnitude), got {value}")
    elif np.issubdtype(like.dtype, np.integer):
        if not np.all(array == np.round(array)):
            raise ValueError(f"{name} must be an integer, got {value}")
        if np.any(array < INT32.min) or np.any(array > INT32.max):
            raise ValueError(f"{name} must fit in int32 (at most {INT32.max:,} in magnitude), got {value}")
    return array.astype(like.dtype)


def check_params(params: Any, names: Iterable[str] | None = None, prefix: str = "") -> None:
    """Checks env params (a dataclass of arrays) against each field's declared range, only the fields in `names`
    when given, then the order relations the params class declares in `ORDERED` ((low, high) field pairs whose
    values must satisfy low <= high). Messages name a field as `prefix + name`."""
    fields = {field.name: field for field in dataclasses.fields(params)}
    for name in fields if names is None else names:
        value = np.asarray(getattr(params, name))
        if np.issubdtype(value.dtype, np.floating) and not np.all(np.isfinite(value)):
            raise ValueError(f"{prefix}{name} must be finite, got {value!s}")
        allowed = declared_range(fields[name])
        if allowed is not None and not allowed.admits(value):
            raise ValueError(f"{prefix}{name} must be {allowed.describe()}, got {value!s}")
    for low, high in getattr(params, "ORDERED", ()):
        if np.any(np.asarray(getattr(params, low)) > np.asarray(getattr(params, high))):
            raise ValueError(
                f"{prefix}{low} ({np.asarray(getattr(params, low))!s}) must not exceed "
                f"{prefix}{high} ({np.asarray(getattr(params, high))!s})"
            )
