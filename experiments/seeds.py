"""The seeds protocol: `python -m experiments.seeds --config NAME --seeds 0-4 --goal 0.95 --minutes 4 [key=value ...]`.

Trains one preset on several seeds, each as a user runs it: `python -m experiments.run --config NAME seed=S` in a
process of its own, into OUT/seed-S. On a host of several GPUs the runs share them out, one run per GPU at a time
(CUDA_VISIBLE_DEVICES); elsewhere they run one after another. Studies started side by side on one host share its
GPUs the same way, a GPU taken by one run of any of them at a time (`GpuPool`), so that several presets' studies
keep every GPU busy without splitting CUDA_VISIBLE_DEVICES by hand. `--runs-per-gpu N` puts up to N runs on each GPU
at once (N at once on a CPU), for runs too small to fill one: the table then says its wall clocks are shared. Never
vmapped together: float-level differences between two programs decide fragile recipes, and a user runs one seed in
one program.

Writes OUT/summary.json and OUT/seeds.md: each seed's placed fraction (its eval.json's success on fresh episodes),
its command's wall clock (from the command's start to its end, summed over the commands of a resumed seed), the
worst seed, the mean with a bootstrap 95% interval, the device and the command. The result is "met" when the worst
seed reaches --goal within --minutes: a result is its worst seed. Studies of one preset's seeds run apart (hosts
lent one at a time, days apart) join into one such row: `python -m experiments.seeds_join STUDY ... --out OUT`.

`--perturb NAME=V1,V2 ... [--worst-corner]` also evaluates each finished seed as a user would,
`python -m experiments.eval OUT/seed-S --episodes N --perturb ... [--worst-corner]` (N from --perturb-episodes,
1,000 by default), in a slot as its training was, and adds a table: each perturbation's placed fraction per seed,
the worst seed and the mean. Config overrides go before --perturb, which takes every word after it.

`python -m experiments.seeds --resume OUT [--stop-after-minutes M]` continues: finished seeds are kept, a stopped
one resumes from its checkpoint. `--stop-after-minutes` passes to each run, for machines that limit a command's
time; a seed whose runs were stopped counts its commands' wall clocks together. A study killed outright (SIGKILL, a
machine's time limit) counts a command it did not see end to the last line of that seed's log.
"""

import sys

from experiments import start_up

if __name__ == "__main__":
    start_up.exit_on_ctrl_c()  # first, as in experiments.run: nothing is written before main()

import argparse
import dataclasses
import json
import os
import pathlib
import signal
import subprocess
import tempfile
import time
from collections.abc import Sequence
from typing import IO

import numpy as np

from experiments import distributed
from experiments.run import minutes
from jaxarm import ranges
from jaxarm.exits import STOPPED_BY_SIGNAL
from jaxarm.runner import filelock, paths, robustness, rundir, stats

SEEDS_FILE = "seeds.json"
"""What was asked (preset, seeds, goal, overrides), each seed's commands' wall clocks so far ("walls") and the
commands started and not yet seen to end ("unended": seed -> the Unix time each started): `--resume` reads it."""
MAX_SEEDS = 1000
"""More separate runs than a study of seeds needs; a bound checked before anything is written."""
POLL_S = 0.5
"""How often a study looks for an ended run or a GPU another study freed, seconds."""
MAX_RUNS_PER_GPU = 16
"""More runs than share one GPU usefully: each holds its own compiled programs and buffers."""
PERTURB_EPISODES = 1000
"""Episodes per row of each seed's robustness table, as `experiments.eval` evaluates by default."""


@dataclasses.dataclass(frozen=True)
class Protocol:
    """What a seeds study asks: the preset and overrides each seed's run takes, which seeds, and the goal."""

    config: str
    seeds: tuple[int, ...]
    goal: float
    minutes: float | None
    overrides: tuple[str, ...]
    runs_per_gpu: int = 1
    perturb: tuple[str, ...] = ()
    worst_corner: bool = False
    perturb_episodes: int = PERTURB_EPISODES

    def __post_init__(self):
        # A study with no slot would wait for one forever (a seeds.json edited by hand).
        if not 1 <= self.runs_per_gpu <= MAX_RUNS_PER_GPU:
            raise ValueError(f"runs_per_gpu must be from 1 to {MAX_RUNS_PER_GPU}, got {self.runs_per_gpu}")
        ranges.check_value("perturb_episodes", self.perturb_episodes, int, ranges.AT_ONCE)

    @property
    def robustness_request(self) -> list[str]:
        """What each finished seed's `experiments.eval` is asked, in the words that name its table
        (`rundir.robustness_stem`); empty where the study asks for no robustness table."""
        return [*self.perturb, *(["--worst-corner"] if self.worst_corner else [])]

    @property
    def robustness_options(self) -> list[str]:
        """The study's options that ask for the robustness tables, as its command line gives them."""
        if not self.robustness_request:
            return []
        episodes = (
            [] if self.perturb_episodes == PERTURB_EPISODES else ["--perturb-episodes", str(self.perturb_episodes)]
        )
        corner = ["--worst-corner"] if self.worst_corner else []
        return [*episodes, *corner, *(["--perturb", *self.perturb] if self.perturb else [])]

    @property
    def command(self) -> str:
        """The study's own command line, as a table cites it."""
        minutes = [] if self.minutes is None else ["--minutes", f"{self.minutes:g}"]
        shared = [] if self.runs_per_gpu == 1 else ["--runs-per-gpu", str(self.runs_per_gpu)]
        seeds = ["--seeds", ",".join(map(str, self.seeds)), "--goal", f"{self.goal:g}", *minutes, *shared]
        # --perturb last: it takes every word after it.
        options = [*seeds, *self.overrides, *self.robustness_options]
        return " ".join(["python -m experiments.seeds --config", self.config, *options])

    def run_command(self, seed: int, out: pathlib.Path) -> list[str]:
        """The command a user types to train `seed` into `out`."""
        return [
            "python", "-m", "experiments.run", "--config", self.config, "--out", str(out), *self.overrides,
            f"seed={seed}",
        ]  # fmt: skip

    def evaluation_command(self, run_dir: pathlib.Path) -> list[str]:
        """The command a user types to evaluate the run in `run_dir` under the study's perturbations."""
        perturb = ["--perturb", *self.perturb] if self.perturb else []
        corner = ["--worst-corner"] if self.worst_corner else []
        episodes = ["--episodes", str(self.perturb_episodes)]
        return ["python", "-m", "experiments.eval", str(run_dir), *episodes, *perturb, *corner]


@dataclasses.dataclass(frozen=True)
class SeedResult:
    """One seed's outcome: placed: its final evaluation's success; wall_s: its commands' wall clocks summed;
    finished: whether it trained its whole budget; device: what it ran on; tries: the tries its run took (a preset
    with a gate, `RunConfig.retry_below`, starts a try again that fails it)."""

    seed: int
    placed: float | None
    wall_s: float
    finished: bool
    device: str | None
    tries: int = 1


def parse_seeds(text: str) -> tuple[int, ...]:
    """`--seeds`: "0-4", "0,3,7" or "0-2,10" to the seeds in that order; ArgumentTypeError for anything else, a
    range that runs backwards, a repeated seed or more than MAX_SEEDS (counted before any range is made)."""
    seeds: list[int] = []
    try:
        spans = [(int(low), int(high or low)) for low, _, high in (part.partition("-") for part in text.split(","))]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seeds as 0-4, 0,3,7 or 0-2,10, got {text!r}") from None
    for low, high in spans:
        if min(low, high) < 0:
            raise argparse.ArgumentTypeError(f"expected seeds each 0 or more, got {text!r}")
        if high < low:
            raise argparse.ArgumentTypeError(f"seeds {low}-{high} run backwards; give {high}-{low}")
        if len(seeds) + high - low + 1 > MAX_SEEDS:
            raise argparse.ArgumentTypeError(f"seeds {text!r}: at most {MAX_SEEDS} seeds")
        seeds.extend(range(low, high + 1))
    if len(set(seeds)) != len(seeds):
        raise argparse.ArgumentTypeError(f"seeds {text!r} name a seed twice")
    return tuple(seeds)


def time_limit(text: str) -> float:
    """`--minutes`: the wall clock each seed's command must end within, more than 0 minutes (with 0 every seed
    trained to its end, only for the study to call the goal not met)."""
    value = minutes(text)
    if value == 0:
        raise argparse.ArgumentTypeError("expected more than 0 minutes: no command ends within 0")
    return value


def runs_per_gpu(text: str) -> int:
    """`--runs-per-gpu`: an integer from 1 to MAX_RUNS_PER_GPU."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= MAX_RUNS_PER_GPU:
        raise argparse.ArgumentTypeError(f"expected an integer from 1 to {MAX_RUNS_PER_GPU}, got {text!r}")
    return value


def fraction(text: str) -> float:
    """`--goal`: a fraction in [0, 1]."""
    try:
        value = float(text)
    except ValueError:
        value = np.nan
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 1], got {text!r}")
    return value


def summarise(
    protocol: Protocol, results: Sequence[SeedResult], tables: dict[int, list[dict] | None] | None = None
) -> dict:
    """The study's row: each seed's placed and wall clock, the worst seed, the mean with its bootstrap interval,
    the devices and whether the worst seed met the goal (in time, where --minutes was given); with the seeds'
    robustness `tables` (`robustness_tables`), a row per perturbation (`robustness_summary`) and each seed's
    worst corner."""
    tables = tables or {}
    placed = np.array([np.nan if result.placed is None else result.placed for result in results])
    done = all(result.finished for result in results)
    in_time = protocol.minutes is None or all(result.wall_s <= 60 * protocol.minutes for result in results)
    low, high = stats.bootstrap_interval(placed) if done else (np.nan, np.nan)
    return {
        "preset": protocol.config,
        "command": protocol.command,
        # What was asked, in full: `experiments.seeds_join` joins studies that asked the same.
        "protocol": dataclasses.asdict(protocol),
        "seeds": [dataclasses.asdict(result) for result in results],
        "worst": float(np.min(placed)) if done else None,
        "mean": float(np.mean(placed)) if done else None,
        "interval": [low, high] if done else None,
        "goal": protocol.goal,
        "minutes": protocol.minutes,
        "devices": sorted({result.device for result in results if result.device}),
        "met": bool(done and in_time and np.min(placed) >= protocol.goal),
        "finished": done,
        "runs_per_gpu": protocol.runs_per_gpu,
        "robustness": robustness_summary(protocol, tables),
        "robustness_command": (
            " ".join(protocol.evaluation_command(pathlib.Path("OUT/seed-S"))) if protocol.robustness_request else None
        ),
        "worst_corners": {str(seed): worst_corner(rows) for seed, rows in tables.items() if rows},
    }


def worst_corner(rows: list[dict]) -> str | None:
    """The params a seed's worst-corner row set, as its table names them; None where it has no such row."""
    prefix = f"{robustness.WORST_CORNER}: "
    return next((row["param"].removeprefix(prefix) for row in rows if row["param"].startswith(prefix)), None)


def row_label(row: dict) -> str:
    """The name of a row of a robustness table, the same for every seed: "nominal", NAME=V, a combined change as
    its table names it, and "worst corner" for every seed's own corner."""
    if row["param"].startswith(robustness.WORST_CORNER):
        return robustness.WORST_CORNER
    return row["param"] if row["value"] is None else f"{row['param']}={row['value']:g}"


def robustness_summary(protocol: Protocol, tables: dict[int, list[dict] | None]) -> list[dict]:
    """A row per perturbation of the seeds' robustness `tables` (seed -> its rows, None where it has none yet), in
    their order: each seed's placed fraction under it (None where its table is missing), then the worst seed and
    the mean with its bootstrap interval once every seed has one."""
    labels = dict.fromkeys(row_label(row) for rows in tables.values() for row in rows or [])
    summary = []
    for label in labels:
        placed = {
            seed: next((row["success_rate"] for row in rows or [] if row_label(row) == label), None)
            for seed, rows in tables.items()
        }
        values = np.array([np.nan if value is None else value for value in placed.values()])
        complete = not np.isnan(values).any()
        low, high = stats.bootstrap_interval(values) if complete else (None, None)
        summary.append(
            {
                "perturbation": label,
                "placed": {str(seed): value for seed, value in placed.items()},
                "worst": float(np.min(values)) if complete else None,
                "mean": float(np.mean(values)) if complete else None,
                "interval": [low, high] if complete else None,
            }
        )
    return summary


def robustness_tables(protocol: Protocol, out: pathlib.Path) -> dict[int, list[dict] | None]:
    """seed -> the rows of its run's robustness table for the study's request (`robustness_rows`), None where it
    has none; {} where the study asks for none."""
    if not protocol.robustness_request:
        return {}
    return {seed: robustness_rows(protocol, out, seed) for seed in protocol.seeds}


def robustness_rows(protocol: Protocol, out: pathlib.Path, seed: int) -> list[dict] | None:
    """The rows of the robustness table `experiments.eval` wrote in seed-S's run of the study's request on its
    episodes (any evaluation seed), of the latest checkpoint it evaluated; None where it wrote none. A table is
    known by what it records (request, episodes, checkpoint): its file's name holds only a digest of the request.
    Unreadable tables and tables of the best checkpoint (`--best`) are not counted."""
    tables = {}
    for path in seed_dir(out, seed).glob("robustness-*.json"):
        try:
            table = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if not isinstance(table, dict) or not isinstance(table.get("rows"), list):
            continue
        asked = table.get("perturb") == protocol.robustness_request
        checkpoint = table.get("checkpoint")
        on_its_episodes = table.get("episodes") == protocol.perturb_episodes
        if asked and on_its_episodes and isinstance(checkpoint, str) and checkpoint.isdigit():
            tables[int(checkpoint)] = table["rows"]
    return tables[max(tables)] if tables else None


def percent(value: float | None) -> str:
    """A fraction as a table shows it, "—" where there is none."""
    return "—" if value is None else f"{100 * value:.1f}%"


def markdown(summary: dict) -> str:
    """`summary` as a table a reader takes in at a glance: a row per seed, then the worst and the mean."""

    joined = [f"`{command}`" for command in summary.get("joined", [])]
    lines = [
        f"`{summary['command']}`",
        *([f"(joined from {'; '.join(joined)})"] if joined else []),
        "",
        "| seed | placed | command wall | tries | device |",
        "|---:|---:|---:|---:|---|",
    ]
    for seed in summary["seeds"]:
        mark = "" if seed["finished"] else " (not finished)"
        lines.append(
            f"| {seed['seed']} | {percent(seed['placed'])}{mark} | {seed['wall_s']:.0f} s | {seed['tries']} | "
            f"{seed['device']} |"
        )
    if summary["runs_per_gpu"] > 1:
        lines += ["", f"{summary['runs_per_gpu']} runs shared each GPU at a time: a wall clock is not one GPU's."]
    if summary["finished"]:
        low, high = summary["interval"]
        goal = f"≥ {percent(summary['goal'])}" + (f" within {summary['minutes']:g} min" if summary["minutes"] else "")
        lines += [
            "",
            f"worst seed {percent(summary['worst'])}; mean {percent(summary['mean'])} (bootstrap 95% interval "
            f"{percent(low)}–{percent(high)}); goal {goal}: {'**met**' if summary['met'] else 'not met'}",
        ]
    if summary["robustness"]:
        lines += ["", *robustness_markdown(summary)]
    return "\n".join(lines) + "\n"


def robustness_markdown(summary: dict) -> list[str]:
    """The lines of the robustness table: a row per perturbation, a column per seed, then the worst and the mean;
    then each seed's worst corner, where one was found."""

    seeds = [str(seed["seed"]) for seed in summary["seeds"]]
    lines = [
        f"Placed under each perturbation (`{summary['robustness_command']}`, each seed's run as OUT/seed-S):",
        "",
        "| perturbation | " + " | ".join(f"seed {seed}" for seed in seeds) + " | worst | mean |",
        "|---|" + "---:|" * (len(seeds) + 2),
    ]
    for row in summary["robustness"]:
        cells = [percent(row["placed"][seed]) for seed in seeds]
        lines.append(
            f"| {row['perturbation']} | {' | '.join(cells)} | {percent(row['worst'])} | {percent(row['mean'])} |"
        )
    corners = summary["worst_corners"]
    if any(corners.values()):
        lines += ["", *(f"- seed {seed}: {corner}" for seed, corner in corners.items() if corner)]
    return lines


def seed_dir(out: pathlib.Path, seed: int) -> pathlib.Path:
    return out / f"seed-{seed}"


def seed_log(out: pathlib.Path, seed: int) -> pathlib.Path:
    """Where the output of seed-S's commands goes, beside its run directory (which holds a run's files alone)."""
    return out / f"seed-{seed}.log"


def seed_result(out: pathlib.Path, seed: int, walls: Sequence[float]) -> SeedResult:
    """What seed-S's run directory holds now: its eval.json where the run evaluated its end."""
    evaluation = rundir.read_evaluation(seed_dir(out, seed))
    return SeedResult(
        seed=seed,
        placed=evaluation.get("success_rate"),
        wall_s=float(sum(walls)),
        finished=bool(evaluation.get("finished")),
        device=evaluation.get("device"),
        tries=tries if isinstance(tries := evaluation.get("tries"), int) else 1,  # runs before gates wrote none
    )


def next_command(protocol: Protocol, out: pathlib.Path, seed: int, stop_after: float | None) -> list[str] | None:
    """The command that moves `seed` on: a resume of its run where that or a stage it trains first has a
    checkpoint, else a new run (into the same directory: a run that died before its first checkpoint starts
    afresh), or None where it has finished."""
    run_dir = seed_dir(out, seed)
    if seed_result(out, seed, []).finished:
        return None
    if rundir.any_stage_checkpoint_files(run_dir):
        command = ["python", "-m", "experiments.run", "--resume", str(run_dir)]
    else:
        command = protocol.run_command(seed, run_dir)
    if stop_after is not None:
        command += ["--stop-after-minutes", f"{stop_after:g}"]
    return command


@dataclasses.dataclass(frozen=True)
class Slot:
    """A place a run goes: a GPU (its CUDA_VISIBLE_DEVICES value), or None on a host without one, and which of the
    runs sharing it (`--runs-per-gpu`) goes there, from 0."""

    gpu: str | None
    share: int = 0

    @property
    def lock_name(self) -> str:
        """The file a study locks to hold this slot; a GPU's first share is the one a study of one run per GPU
        takes."""
        return f"gpu-{self.gpu}.lock" if self.share == 0 else f"gpu-{self.gpu}-{self.share}.lock"


def gpu_slots(runs_per_gpu: int) -> list[Slot]:
    """Where runs go at once: `runs_per_gpu` per visible GPU, else as many with no GPU named; each GPU's first
    share before any GPU's second, so that runs spread over the GPUs before they share one."""
    count = distributed.gpus_here()
    gpus: list[str | None] = list(distributed.local_gpus(count)) if count else [None]
    return [Slot(gpu, share) for share in range(runs_per_gpu) for gpu in gpus]


def gpu_lock_dir() -> pathlib.Path:
    """Where this host's studies lock the GPUs they run on: one directory per user, as GPUs are the host's."""
    return pathlib.Path(tempfile.gettempdir()) / f"jaxarm-gpus-{os.getuid()}"


class GpuPool:
    """The slots a study starts runs in (`gpu_slots`), shared with every other study on this host: a slot of a GPU
    is taken by holding an exclusive lock on its file in `lock_dir` while a run uses it, so two studies never put
    runs in one slot at once, and a GPU holds at most as many runs as the largest `--runs-per-gpu` of the studies
    on it; the OS drops the lock of a study that dies. Slots with no GPU (a host without one) are this study's
    alone: runs on the CPU take turns in them within a study."""

    def __init__(self, slots: list[Slot], lock_dir: pathlib.Path):
        self.slots = slots
        self.lock_dir = lock_dir
        self.held: dict[Slot, IO | None] = {}

    def take(self) -> Slot | None:
        """A slot neither this study nor another holds, now taken; None if none."""
        for slot in self.slots:
            if slot in self.held:
                continue
            if slot.gpu is None:
                self.held[slot] = None
                return slot
            self.lock_dir.mkdir(parents=True, exist_ok=True)
            handle = (self.lock_dir / slot.lock_name).open("w")
            if not filelock.try_lock(handle):
                handle.close()
                continue
            self.held[slot] = handle
            return slot
        return None

    def give_back(self, slot: Slot) -> None:
        """Frees `slot` (taken by `take`) for this study and the others."""
        handle = self.held.pop(slot)
        if handle is not None:
            handle.close()


def evaluation_command(protocol: Protocol, out: pathlib.Path, seed: int) -> list[str] | None:
    """The command that evaluates `seed`'s finished run under the study's perturbations, or None where the study
    asks for none, the run has not finished or its table is written."""
    if not protocol.robustness_request or not seed_result(out, seed, []).finished:
        return None
    return None if robustness_rows(protocol, out, seed) else protocol.evaluation_command(seed_dir(out, seed))


@dataclasses.dataclass(frozen=True)
class Command:
    """A command the study runs for `seed`: its training's next (`next_command`), or with `evaluating` its
    robustness evaluation (`evaluation_command`)."""

    seed: int
    argv: list[str]
    evaluating: bool = False


def pending_commands(protocol: Protocol, out: pathlib.Path, stop_after: float | None) -> list[Command]:
    """Each unfinished seed's next training command, then each finished seed's robustness evaluation not yet
    written."""
    training = [
        Command(seed, argv) for seed in protocol.seeds if (argv := next_command(protocol, out, seed, stop_after))
    ]
    evaluations = [
        Command(seed, argv, True) for seed in protocol.seeds if (argv := evaluation_command(protocol, out, seed))
    ]
    return training + evaluations


@dataclasses.dataclass(frozen=True)
class Failures:
    """The seeds whose training commands (runs) and whose robustness evaluations ended with a status but 0."""

    runs: list[int] = dataclasses.field(default_factory=list)
    evaluations: list[int] = dataclasses.field(default_factory=list)


def evaluation_after(protocol: Protocol, out: pathlib.Path, seed: int, returncode: int) -> list[Command]:
    """The robustness evaluation `seed` needs now that a training command of it ended with `returncode`: none
    where the command failed or the seed's run has not finished (`evaluation_command`)."""
    argv = evaluation_command(protocol, out, seed) if returncode == 0 else None
    return [Command(seed, argv, True)] if argv else []


def evaluation_ended(seed: int, returncode: int, failures: Failures) -> None:
    """Says how `seed`'s robustness evaluation ended, and counts it in `failures` where it failed."""
    if returncode != 0:
        failures.evaluations.append(seed)
    print(f"seed {seed}: robustness evaluation rc {returncode}", flush=True)


def train_seeds(
    protocol: Protocol,
    out: pathlib.Path,
    walls: dict[int, list[float]],
    unended: dict[int, float],
    stop_after: float | None,
    record,
) -> Failures:
    """Runs every unfinished seed's next command, as many at once as there are GPUs free of other studies'
    runs (`GpuPool`), appending each command's wall clock to `walls[seed]` and calling `record()` after each ends,
    an interrupted one too: on Ctrl-C or SIGTERM the runs are told to stop (they checkpoint) and waited for, so
    that none is left running. Each command's start stays in `unended[seed]` (Unix time, recorded) until it ends:
    a study killed outright leaves it there for `--resume` (`unended_walls`). A seed that has finished then gets
    its robustness evaluation where the study asks for one (`evaluation_command`), its time not counted in the
    seed's wall clock. Returns the seeds whose commands failed."""
    queue = pending_commands(protocol, out, stop_after)
    pool = GpuPool(gpu_slots(protocol.runs_per_gpu), gpu_lock_dir())
    running: dict[subprocess.Popen, tuple[Command, Slot, float]] = {}
    failures = Failures()

    def finish(process: subprocess.Popen) -> None:
        command, slot, started = running.pop(process)
        seed = command.seed
        pool.give_back(slot)
        if command.evaluating:
            return evaluation_ended(seed, process.returncode, failures)
        if process.returncode != 0:
            failures.runs.append(seed)
        walls.setdefault(seed, []).append(time.perf_counter() - started)
        unended.pop(seed, None)
        record()
        result = seed_result(out, seed, walls[seed])
        state = f"placed {result.placed:.3f}" if result.finished and result.placed is not None else "not finished"
        print(f"seed {seed}: rc {process.returncode}, {state} after {result.wall_s:.0f} s", flush=True)
        queue.extend(evaluation_after(protocol, out, seed, process.returncode))

    try:
        while queue or running:
            while queue:
                if (slot := pool.take()) is None:
                    break
                command = queue.pop(0)
                process = start_run(out, command.seed, command.argv, slot.gpu, shared=protocol.runs_per_gpu > 1)
                running[process] = (command, slot, time.perf_counter())
                if not command.evaluating:
                    unended[command.seed] = time.time()
                    record()
            if ended := first_ended(list(running)):
                finish(ended)
            else:  # a run of this study may end, or another study may free a GPU
                time.sleep(POLL_S)
    except KeyboardInterrupt:
        signal_all(running, signal.SIGTERM)  # each run checkpoints at its next chunk end and stops
        raise
    finally:
        while running:
            try:
                finish(wait_any(list(running)))
            except KeyboardInterrupt:
                signal_all(running, signal.SIGINT)  # a second Ctrl-C: the runs' second, which ends them at once
    return failures


def signal_all(running: dict[subprocess.Popen, tuple], signum: int) -> None:
    """Sends `signum` to each run still running: they run in sessions of their own, out of a terminal's reach,
    so that they hear one signal at a time, from here."""
    for process in running:
        if process.poll() is None:
            process.send_signal(signum)


def start_run(out: pathlib.Path, seed: int, command: list[str], gpu: str | None, shared: bool) -> subprocess.Popen:
    """Starts `command` (`python -m experiments.run ...` or `experiments.eval ...`) with this interpreter, on `gpu`
    alone where one is named, its output appended to OUT/seed-S.log. A run on a `shared` GPU allocates its memory
    as it goes (unless the environment says otherwise): JAX takes 75% of a GPU at its start, leaving too little for
    a second run."""
    env = dict(os.environ) if gpu is None else {**os.environ, "CUDA_VISIBLE_DEVICES": gpu}
    if shared:
        env.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")
    print(f"seed {seed}{'' if gpu is None else f' on GPU {gpu}'}: {' '.join(command)} (log {seed_log(out, seed)})")
    with seed_log(out, seed).open("a") as log:
        return subprocess.Popen([sys.executable, *command[1:]], env=env, stdout=log, stderr=log, start_new_session=True)


def first_ended(processes: list[subprocess.Popen]) -> subprocess.Popen | None:
    """One of `processes` that has ended, or None while all run."""
    return next((process for process in processes if process.poll() is not None), None)


def wait_any(processes: list[subprocess.Popen]) -> subprocess.Popen:
    """The first of `processes` to end."""
    while (process := first_ended(processes)) is None:
        time.sleep(POLL_S)
    return process


def parse_args(argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.seeds", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--config", help="preset name (python -m experiments.run --list)")
    parser.add_argument("--seeds", type=parse_seeds, default=parse_seeds("0-4"), help="e.g. 0-4 (the default)")
    parser.add_argument("--goal", type=fraction, default=0.9, help="the placed fraction each seed must reach")
    parser.add_argument("--minutes", type=time_limit, help="each seed's command must end within this wall clock")
    parser.add_argument("--out", type=paths.given, help="study directory (default runs/seeds-<config>-<timestamp>)")
    parser.add_argument("--resume", metavar="OUT", help="continue the study in OUT")
    parser.add_argument(
        "--stop-after-minutes", type=minutes, help="passed to each run: checkpoint and stop after this wall clock"
    )
    parser.add_argument(
        "--runs-per-gpu", type=runs_per_gpu, help="runs sharing each GPU at once (default 1; on a CPU, runs at once)"
    )
    parser.add_argument(
        "--perturb",
        nargs="+",
        metavar="NAME=V1,V2",
        default=[],
        help="evaluate each finished seed under these changes of its env's params, as experiments.eval --perturb "
        "does; give config overrides before it",
    )
    parser.add_argument(
        "--worst-corner",
        action="store_true",
        help="evaluate each finished seed at its worst corner, as experiments.eval --worst-corner does",
    )
    parser.add_argument(
        "--perturb-episodes",
        type=int,
        help=f"episodes per perturbation of each seed's evaluation (default {PERTURB_EPISODES:,})",
    )
    parser.add_argument("overrides", nargs="*", help="config overrides key=value, the same for every seed")
    args = parser.parse_args(argv)
    if bool(args.config) == bool(args.resume):
        parser.error("give --config NAME (a new study) or --resume OUT (a stopped one)")
    asked = [
        args.overrides, args.out, args.runs_per_gpu, args.perturb, args.worst_corner, args.perturb_episodes,
    ]  # fmt: skip
    if args.resume and any(asked):  # else left aside without a word
        parser.error(
            "--resume takes what the study was asked, and where, from its seeds.json; give no overrides, --out, "
            "--runs-per-gpu, --perturb, --worst-corner or --perturb-episodes"
        )
    if args.perturb_episodes is not None and not (args.perturb or args.worst_corner):
        parser.error("--perturb-episodes counts the episodes of --perturb or --worst-corner; give one of them")
    return args


def protocol_from(saved: dict) -> Protocol:
    """The protocol a study recorded (its seeds.json, or the "protocol" of its summary.json); KeyError, TypeError or
    ValueError where the record is damaged."""
    return Protocol(
        config=str(saved["config"]),
        seeds=tuple(int(seed) for seed in saved["seeds"]),
        goal=float(saved["goal"]),
        minutes=None if saved["minutes"] is None else float(saved["minutes"]),
        overrides=tuple(str(item) for item in saved["overrides"]),
        runs_per_gpu=int(saved.get("runs_per_gpu", 1)),  # studies before the option ran one run per GPU
        # Studies before the options evaluated no perturbation.
        perturb=tuple(str(item) for item in saved.get("perturb", [])),
        worst_corner=bool(saved.get("worst_corner", False)),
        perturb_episodes=int(saved.get("perturb_episodes", PERTURB_EPISODES)),
    )


def read_study(out: pathlib.Path) -> tuple[Protocol, dict[int, list[float]], dict[int, float]]:
    """The protocol, the wall clocks so far and the starts of commands not seen to end (`SEEDS_FILE`) of the study
    in `out`; ValueError in one line naming what is wrong."""
    path = out / SEEDS_FILE
    try:
        saved = json.loads(path.read_text())
        protocol = protocol_from(saved)
        walls = {int(seed): [float(wall) for wall in values] for seed, values in saved["walls"].items()}
        # Studies before it recorded no starts.
        unended = {int(seed): float(started) for seed, started in saved.get("unended", {}).items()}
    except FileNotFoundError:
        raise ValueError(f"{out} holds no {SEEDS_FILE}: not a study of experiments.seeds") from None
    except (OSError, ValueError, TypeError, KeyError, AttributeError) as error:
        raise ValueError(f"{path} is damaged ({type(error).__name__}: {error}); start a new study") from None
    return protocol, walls, unended


def unended_walls(out: pathlib.Path, unended: dict[int, float]) -> dict[int, float]:
    """The wall clocks of the commands a study started and never saw end (it was killed outright: SIGKILL, a
    machine's time limit), seed -> seconds, each to the last line its seed's log got: a run writes there to its
    end, its checkpoint's line last. A command whose log is gone counts nothing."""
    logs = {seed: seed_log(out, seed) for seed in unended}
    return {seed: max(0.0, log.stat().st_mtime - unended[seed]) for seed, log in logs.items() if log.exists()}


def interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def main(argv=None) -> int:
    # Start-up is over: Ctrl-C raises KeyboardInterrupt again. A cluster's time limit or `timeout` sends SIGTERM:
    # the study stops as on Ctrl-C.
    start_up.start_up_over()
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        return study(parse_args(sys.argv[1:] if argv is None else argv))
    finally:
        signal.signal(signal.SIGTERM, previous)


def open_study(args: argparse.Namespace) -> tuple[Protocol, pathlib.Path, dict[int, list[float]]]:
    """(protocol, directory, wall clocks so far) of the study `args` ask for: a stopped one's, or a new one's in a
    directory that holds no study yet; ValueError in one line for an unknown preset, a bad override or such a
    directory, before any run starts."""
    if args.resume:
        out = pathlib.Path(args.resume)
        protocol, walls, unended = read_study(out)
        for seed, wall in unended_walls(out, unended).items():
            walls.setdefault(seed, []).append(wall)
            print(
                f"seed {seed}: its last command was not seen to end (the study was killed); its wall clock is counted "
                f"to the last line of its log: {wall:.0f} s",
                file=sys.stderr,
            )
        return protocol, out, walls
    import jax

    from experiments import configs
    from jaxarm.agents.common.config import apply_overrides

    # Validating builds the env, which starts JAX's backend: on the CPU, so that this process takes none of the
    # GPUs' memory from the runs (on a GPU, JAX takes most of it at start: two runs failed so, out of memory).
    jax.config.update("jax_platforms", "cpu")
    # Refused here, not once per seed: the largest seed, as any other, must be a seed the config takes.
    config = apply_overrides(configs.get(args.config), [*args.overrides, f"seed={max(args.seeds)}"])
    protocol = Protocol(
        args.config,
        args.seeds,
        args.goal,
        args.minutes,
        tuple(args.overrides),
        args.runs_per_gpu or 1,
        tuple(args.perturb),
        args.worst_corner,
        PERTURB_EPISODES if args.perturb_episodes is None else args.perturb_episodes,
    )
    check_robustness_request(protocol, config)
    out = pathlib.Path(args.out) if args.out else rundir.new_run_dir(f"seeds-{args.config}")
    paths.check_output_dir(out, "--out")
    if (out / SEEDS_FILE).exists():
        raise ValueError(f"{out} holds a study already; continue it with --resume {out}, or give another --out")
    out.mkdir(parents=True, exist_ok=True)
    return protocol, out, {}


def check_robustness_request(protocol: Protocol, config) -> None:
    """ValueError in one line for a perturbation `experiments.eval` would refuse the seeds' runs (`config`, the
    resolved preset) after their training: words that are not NAME=V1,V2 or NAME=V+NAME=V, a name that is not a
    param of the env (a config override given after --perturb, say), a value outside its range; or --worst-corner
    where the preset randomises nothing."""
    if protocol.worst_corner and not config.randomize:
        raise ValueError(f"--worst-corner: {protocol.config} randomises no env param")
    if not protocol.perturb:
        return
    _, env_params = config.make_eval_env()
    try:
        for text in protocol.perturb:
            if "+" in text:
                change = robustness.parse_combined(text)
                robustness.check_perturbations(env_params, {name: [value] for name, value in change.items()})
            else:
                robustness.check_perturbations(env_params, dict([robustness.parse_perturbation(text)]))
    except robustness.PerturbationError as error:
        raise ValueError(f"--perturb: {error} (config overrides go before --perturb)") from None


def study(args: argparse.Namespace) -> int:
    """Runs or continues the study `args` ask for; the exit code."""
    try:
        protocol, out, walls = open_study(args)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2

    unended: dict[int, float] = {}

    def record() -> None:
        rundir.write_json(out / SEEDS_FILE, {**dataclasses.asdict(protocol), "walls": walls, "unended": unended})

    record()
    try:
        failures = train_seeds(protocol, out, walls, unended, args.stop_after_minutes, record)
    except KeyboardInterrupt:
        print(f"\ninterrupted; continue with: python -m experiments.seeds --resume {out}", file=sys.stderr)
        return STOPPED_BY_SIGNAL
    results = [seed_result(out, seed, walls.get(seed, [])) for seed in protocol.seeds]
    summary = summarise(protocol, results, robustness_tables(protocol, out))
    rundir.write_json(out / "summary.json", summary)
    (out / "seeds.md").write_text(markdown(summary))
    print(markdown(summary), end="")
    resume = f"python -m experiments.seeds --resume {out}"
    # A study whose runs failed (a seed the config refuses, a full disk, a crash) failed (rc 0 before).
    for kind, failed in (("runs", failures.runs), ("robustness evaluations", failures.evaluations)):
        if failed:
            logs = ", ".join(str(seed_log(out, seed)) for seed in failed)
            print(
                f"error: the {kind} of seeds {', '.join(map(str, failed))} failed (their logs say why: {logs}); fix "
                f"that and continue with: {resume}",
                file=sys.stderr,
            )
    if failures.runs or failures.evaluations:
        return 2
    if not summary["finished"]:
        unfinished = ", ".join(str(seed_log(out, result.seed)) for result in results if not result.finished)
        print(f"some seeds did not finish (their logs say why: {unfinished}); continue them with: {resume}")
    return 0


if __name__ == "__main__":
    start_up.exit_with(main)
