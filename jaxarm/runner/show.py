"""`--show`: every config field (type, value, docstring) and the env's params (value, default, docstring).

The docs are the `Attributes:` sections of the config's and the params' class docstrings, where each field is
documented once.
"""

import dataclasses
import re
import textwrap
import typing

import numpy as np

from jaxarm import ranges
from jaxarm.agents.common.config import RunConfig

_ENTRY = re.compile(r"^\s{2,}(\w+): (.*)$")


def attribute_docs(cls: type) -> dict[str, str]:
    """{field: its line(s) in the `Attributes:` sections of `cls` and its bases' docstrings}."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        doc = klass.__dict__.get("__doc__") or ""
        if "Attributes" not in doc:
            continue
        current = None
        for line in doc.split("Attributes", 1)[1].splitlines()[1:]:
            match = _ENTRY.match(line)
            if match and len(line) - len(line.lstrip()) <= 6:
                current = match.group(1)
                docs[current] = match.group(2).strip()
            elif current and line.strip():
                docs[current] += " " + line.strip()
            elif not line.strip() and current:
                current = None
    return docs


def _type_name(annotation) -> str:
    return annotation.__name__ if isinstance(annotation, type) else str(annotation).replace("typing.", "")


def _wrapped(doc: str) -> str:
    return textwrap.fill(doc, width=116, initial_indent=" " * 6, subsequent_indent=" " * 6)


def _allowed(field: dataclasses.Field, before: str = ", ", after: str = "") -> str:
    allowed = ranges.declared_range(field)
    return f"{before}{allowed.describe()}{after}" if allowed else ""


def config_lines(config: RunConfig) -> list[str]:
    """One line per config field: name, type, this config's value (and the class default where it differs), doc."""
    hints = typing.get_type_hints(type(config))
    docs = attribute_docs(type(config))
    lines = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        default = field.default
        changed = "" if value == default else f"  (default {default!r})"
        marks = " [dynamic]" if field.metadata.get("dynamic") else ""
        lines.append(f"  {field.name} ({_type_name(hints[field.name])}{marks}{_allowed(field)}) = {value!r}{changed}")
        if field.name in docs:
            lines.append(_wrapped(docs[field.name]))
    return lines


def _plain(value) -> str:
    array = np.asarray(value)
    return str(array[()]) if array.ndim == 0 else np.array2string(array, separator=",", precision=4)


def env_param_lines(config: RunConfig) -> list[str]:
    """One line per env param: name, this config's training value (and the env default where it differs), doc."""
    env, params = config.make_env()
    defaults = env.default_params()
    docs = attribute_docs(type(params))
    lines = []
    for field in dataclasses.fields(params):
        value, default = _plain(getattr(params, field.name)), _plain(getattr(defaults, field.name))
        changed = "" if value == default else f"  (default {default})"
        lines.append(f"  env_params.{field.name}{_allowed(field, ' (', ')')} = {value}{changed}")
        if field.name in docs:
            lines.append(_wrapped(docs[field.name]))
    return lines


def describe(config: RunConfig, preset: str) -> str:
    """The text `--show` prints for `config` (the preset `preset` with any overrides)."""
    return "\n".join(
        [
            f"{preset}: {type(config).__name__} (set any field as key=value; lists as 64,64 or [64,64])",
            *config_lines(config),
            f"env {config.env!r} params (env_params.NAME=VALUE; eval_env_params.NAME=VALUE for evaluation only):",
            *env_param_lines(config),
        ]
    )
