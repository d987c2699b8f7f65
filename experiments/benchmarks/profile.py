"""Where a learner's update spends its time, phase by phase, from one profiled call.

Compiles `--updates` updates of a preset's learner into one program (as the runner compiles a chunk, with
`Trainer.compiler_options`), runs it once to warm up, once timed, and once under `jax.profiler.trace`. Every op
the device ran (GPU kernels and copies; on a CPU, XLA's thunks) is booked to the first of `--phases` that its
HLO instruction's name stack holds: PPO runs its phases under the named scopes `collect`, `advantages` and
`sgd`; inside collect, `AutoReset` draws its starts under `auto_reset` and the Panda envs step their physics under
`physics` and pose their bodies under `kinematics` (e.g. `--phases auto_reset,physics,kinematics,collect,sgd`;
XLA fuses many of a reset's ops into the selects that follow it, which keep their own scope). Ops whose
instruction carries no name stack (copies XLA inserted, and instructions such as those of MJX's constraint solver
whose metadata XLA dropped) are `unattributed`.

On a GPU, XLA records runs of kernels as CUDA graphs ("command buffers"); the profile shows each graph as one op
with no name stack. Run with `XLA_FLAGS=--xla_gpu_enable_command_buffer=` to book every kernel to its phase: the
wall clock then grows by the launch gaps, the busy times per phase do not.
"""

import argparse
import collections
import dataclasses
import glob
import re
import shutil
import tempfile
from collections.abc import Sequence

import jax

from experiments import configs, start_up
from experiments.benchmarks.arguments import count
from experiments.benchmarks.record import add_out_argument, write_record
from experiments.benchmarks.timing import compile_updates, timed
from jaxarm.agents.common.config import apply_overrides

UNATTRIBUTED = "unattributed"
INSTRUCTION = re.compile(r"^\s*(?:ROOT )?%?([\w.\-]+) = .*?op_name=\"([^\"]*)\"", re.MULTILINE)


@dataclasses.dataclass(frozen=True)
class PhaseTime:
    """Busy time of one phase over the profiled call: seconds summed over its ops, and their count."""

    phase: str
    seconds: float
    ops: int


def op_names(hlo_text: str) -> dict[str, str]:
    """{instruction name: its name stack (`op_name` metadata)} for every instruction of a compiled HLO module."""
    return {match.group(1): match.group(2) for match in INSTRUCTION.finditer(hlo_text)}


TRANSFORMED_SCOPE = re.compile(r"^(?:\w+\()+([^()]*)\)+$")
"""A scope a transformation renamed: `vmap(auto_reset)` is `auto_reset` vmapped."""


def phase_of(name_stack: str, phases: tuple[str, ...]) -> str:
    """The first of `phases` that `name_stack` holds as a whole scope (also under a transformation, such as
    `vmap(name)`), else `UNATTRIBUTED`."""
    scopes = [TRANSFORMED_SCOPE.sub(r"\1", scope) for scope in name_stack.split("/")]
    return next((phase for phase in phases if phase in scopes), UNATTRIBUTED)


def leaf_events(events: list) -> list:
    """The events of one profile line that contain no other: XLA:CPU nests a loop's body ops inside the loop's own
    event on the same thread, and only the innermost ops are work (GPU kernels on a stream never nest)."""
    ordered = sorted(events, key=lambda event: (event.start_ns, -event.duration_ns))
    return [
        event
        for index, event in enumerate(ordered)
        if index + 1 == len(ordered) or ordered[index + 1].start_ns >= event.start_ns + event.duration_ns
    ]


def device_ops(profile_path: str):
    """(hlo op name, seconds) of every innermost op the device ran in an `.xplane.pb` profile: GPU planes where
    there are any, else XLA:CPU's runtime threads (whose busy times add up over threads running at once)."""
    # ProfileData's planes, lines and events are one-pass iterators: materialise them once.
    planes = {
        plane.name: [list(line.events) for line in plane.lines]
        for plane in jax.profiler.ProfileData.from_file(profile_path).planes
    }
    device_lines = [lines for name, lines in planes.items() if name.startswith("/device:") and lines]
    for lines in device_lines or [planes.get("/host:CPU", [])]:
        for events in lines:
            for event in leaf_events([event for event in events if "hlo_op" in dict(event.stats)]):
                yield dict(event.stats)["hlo_op"], event.duration_ns * 1e-9


def phase_times(ops, names: dict[str, str], phases: tuple[str, ...]) -> list[PhaseTime]:
    """Busy time per phase (in `phases` order, `UNATTRIBUTED` last) of `(hlo op, seconds)` pairs."""
    seconds: collections.defaultdict[str, float] = collections.defaultdict(float)
    counts: collections.defaultdict[str, int] = collections.defaultdict(int)
    for hlo_op, duration in ops:
        phase = phase_of(names.get(hlo_op, ""), phases)
        seconds[phase] += duration
        counts[phase] += 1
    return [PhaseTime(phase, seconds[phase], counts[phase]) for phase in (*phases, UNATTRIBUTED)]


def profile_updates(config, num_updates: int, phases: tuple[str, ...]) -> tuple[float, list[PhaseTime]]:
    """(wall seconds of `num_updates` updates, busy time per phase of another such call) of `config`'s learner."""
    compiled, state, hparams, _ = compile_updates(config, num_updates)
    names = op_names(compiled.as_text())
    timed(compiled, state, hparams)  # warm-up
    wall = timed(compiled, state, hparams)
    with tempfile.TemporaryDirectory() as trace_dir, start_up.CleanedOnCtrlC(lambda: shutil.rmtree(trace_dir, True)):
        with jax.profiler.trace(trace_dir):
            jax.block_until_ready(compiled(state, hparams))
        (profile_path,) = glob.glob(f"{trace_dir}/**/*.xplane.pb", recursive=True)
        return wall, phase_times(device_ops(profile_path), names, phases)


def format_table(wall: float, times: list[PhaseTime], num_updates: int) -> str:
    busy = sum(phase_time.seconds for phase_time in times)
    lines = ["| phase | busy ms per update | share of busy | ops per update |", "|---|---:|---:|---:|"]
    lines += [
        f"| {phase_time.phase} | {phase_time.seconds / num_updates * 1e3:.2f} "
        f"| {phase_time.seconds / max(busy, 1e-12):.1%} | {phase_time.ops / num_updates:,.0f} |"
        for phase_time in times
    ]
    lines.append(f"| all ops (busy) | {busy / num_updates * 1e3:.2f} | | |")
    lines.append(f"| wall clock | {wall / num_updates * 1e3:.2f} | | |")
    return "\n".join(lines)


def main(argv: Sequence[str]) -> None:
    parser = argparse.ArgumentParser(prog="python -m experiments.bench profile", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="ppo_arm2d", help="preset name")
    parser.add_argument("--updates", type=count, default=4, help="updates in the profiled program")
    parser.add_argument("--phases", default="collect,advantages,sgd", help="named scopes to book time to")
    parser.add_argument("overrides", nargs="*", help="config overrides key=value")
    add_out_argument(parser)
    args = parser.parse_args(argv)
    if args.updates < 1:
        parser.error(f"--updates must be at least 1, not {args.updates}")
    try:
        config = apply_overrides(configs.get(args.config), args.overrides)
    except ValueError as error:
        parser.error(str(error))
    phases = tuple(phase for phase in args.phases.split(",") if phase)
    print(
        f"device: {jax.devices()[0].device_kind}; jax {jax.__version__}; {args.config} {' '.join(args.overrides)}; "
        f"{args.updates} updates in one program",
        flush=True,
    )
    wall, times = profile_updates(config, args.updates, phases)
    print(format_table(wall, times, args.updates))
    rows = [
        {
            "phase": phase_time.phase,
            "busy_ms_per_update": phase_time.seconds / args.updates * 1e3,
            "ops_per_update": phase_time.ops / args.updates,
        }
        for phase_time in times
    ]
    write_record(
        args.out,
        "profile",
        argv,
        rows,
        config=args.config,
        overrides=args.overrides,
        updates=args.updates,
        wall_ms_per_update=wall / args.updates * 1e3,
    )
