"""The command-line options that make a command one of several processes (`jax.distributed`), shared by run
and sweep: on SLURM the processes find each other alone; elsewhere `--coordinator`, `--num-processes` and
`--process-id` say how; `--local-processes N` forks N of them on this host, one GPU each (1: the command
runs alone, on every GPU).

One process per GPU is how Warp's own multi-GPU examples run; BENCHMARKS.md#devices compares it with one process
driving every GPU. Where a PPO run on this host steps MJX Warp and sees several GPUs, it starts one process per
GPU by itself (`local_process_count`). That decision is taken before JAX starts its backend, which takes most of
every GPU's memory: GPUs are counted with `nvidia-smi`, never through JAX.
"""

import argparse
import atexit
import contextlib
import ctypes
import io
import itertools
import mmap
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from typing import NoReturn

import jax
from jax._src import distributed as jax_distributed
from jax._src import xla_bridge
from jax.experimental import multihost_utils

from jaxarm.envs.panda.mjx_impl import Impl
from jaxarm.exits import STOPPED_BY_SIGNAL

LOCAL_PROCESSES = "--local-processes"
STOP_GRACE_S = 60.0
"""How long the others get to checkpoint and stop once one local process has failed (then they are killed)."""
REPORT_GRACE_S = 60.0
"""How long a process that stopped on an error it reported waits for the others to report theirs before it leaves
(`others_reported`): gone first, process 0 would take JAX's coordination service with it, and JAX aborts a
process that loses it (SIGABRT, after a block of C++ logs) before that process has said why it stops."""
POLL_S = 0.2
MAX_PORT = 65535
PR_SET_PDEATHSIG = 1
"""prctl's option (linux/prctl.h) that sends a process a signal when the thread that forked it ends."""
WAIT_FOR_PEERS_S = 900
"""How long a process that joined waits for the others to open the collectives (their backends starting) and at the
end (JAX's shutdown barrier, while process 0 writes the last files): minutes on a loaded CPU, where JAX's default
of 300 s was near. Joining itself keeps JAX's 300 s by default (`--join-timeout`): a process whose peers never
start should not wait longer."""
JOIN_TIMEOUT_S = 300.0
"""How long a process waits by default for every other to start and join (JAX's own default deadline)."""
MAX_JOIN_TIMEOUT_S = 86_400.0
JAX_DEADLINE_AFTER_S = 60
"""How much later than `--join-timeout` JAX's own joining deadline is set: JAX aborts the process at its deadline
(SIGABRT, with a C++ stack trace), so this module's own line (`never_joined`) must come first."""
PEER_LOST = ("Gloo", "coordination service", "Connection reset by peer", "DEADLINE_EXCEEDED")
"""Words of JAX's errors in a process whose peers have gone (their collectives or its coordination service)."""
_peer_failed = mmap.mmap(-1, 1)
"""One byte this process and the processes it forks (`spawn`) share: set by the launcher before it stops the others
where one failed (`stopped_for_a_failed_peer`)."""


def add_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """Adds `--distributed` and the three options that go with it; `what` names the folder every process shares."""
    parser.add_argument(
        "--distributed",
        action="store_true",
        help="one of several processes (several hosts, or one process per GPU): run the same command in each, "
        f"with the same {what}; on SLURM the processes find each other alone, elsewhere give the options below",
    )
    parser.add_argument(
        "--coordinator", metavar="HOST:PORT", type=coordinator_address, help="with --distributed: process 0's address"
    )
    parser.add_argument("--num-processes", type=int, help="with --distributed: how many processes in all")
    parser.add_argument("--process-id", type=int, help="with --distributed: this process's index, from 0")
    parser.add_argument(
        "--join-timeout",
        type=float,
        metavar="SECONDS",
        help=f"with --distributed: how long to wait for every process to start and join (default {JOIN_TIMEOUT_S:.0f})",
    )
    parser.add_argument(
        LOCAL_PROCESSES,
        type=int,
        metavar="N",
        help="start N processes of this command on this host, one GPU each (CUDA_VISIBLE_DEVICES), joined as "
        "--distributed: the way MJX Warp uses several GPUs. `run` starts one per visible GPU by itself for PPO "
        "on MJX Warp; 1 keeps it one process, driving every GPU",
    )


def coordinator_address(text: str) -> str:
    """`--coordinator`'s HOST:PORT, as given; argparse's error where the host or the port is missing or the port is
    no TCP port (JAX's own parsing fails on them with an IndexError traceback)."""
    host, colon, port = text.rpartition(":")
    if not colon or not host:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT (e.g. 10.0.0.1:1234)")
    if not (port.isdigit() and 1 <= int(port) <= MAX_PORT):
        raise argparse.ArgumentTypeError(f"{text!r}: its port {port!r} is not a number from 1 to {MAX_PORT}")
    return text


def port_in_use(port: int) -> bool:
    """Whether a process on this host listens on TCP `port` (on any address)."""
    with socket.socket() as probe:
        # Connections of an earlier run still closing (TIME_WAIT) do not keep JAX's coordinator off the port.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("", port))
        except OSError:
            return True
    return False


def check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Exits with the usage where the joining options come without `--distributed`, where `--process-id` is not
    below `--num-processes`, where this process is the coordinator (process 0) and its port is taken here (JAX
    would find out only at its deadline, or abort), or where `--local-processes` asks more processes than the host
    has cores."""
    joining = (args.coordinator, args.num_processes, args.process_id, args.join_timeout)
    if any(option is not None for option in joining) and not args.distributed:
        parser.error("--coordinator, --num-processes, --process-id and --join-timeout go with --distributed")
    if args.join_timeout is not None and not 0 < args.join_timeout <= MAX_JOIN_TIMEOUT_S:
        parser.error(f"--join-timeout takes seconds in (0, {MAX_JOIN_TIMEOUT_S:.0f}], got {args.join_timeout}")
    if args.num_processes is not None and args.num_processes < 1:
        parser.error(f"--num-processes takes a count of 1 or more, got {args.num_processes}")
    if args.process_id is not None and args.process_id < 0:
        parser.error(f"--process-id takes 0 or more, got {args.process_id}")
    if None not in (args.process_id, args.num_processes) and args.process_id >= args.num_processes:
        parser.error(f"--process-id {args.process_id} is not below --num-processes {args.num_processes}")
    if args.coordinator is not None and args.process_id == 0:
        port = int(args.coordinator.rpartition(":")[2])
        if port_in_use(port):
            parser.error(
                f"--coordinator {args.coordinator}: port {port} is in use on this host, where process 0 listens; "
                "choose a free one"
            )
    if args.local_processes is not None and (args.distributed or args.local_processes < 1):
        parser.error(f"{LOCAL_PROCESSES} takes a count of 1 or more, without --distributed (it adds it)")
    cores = os.cpu_count() or 1
    if args.local_processes is not None and args.local_processes > cores:
        # Each forks from this one and starts JAX: 100000 asked forked ~2,600 on a 2-core host (load 1,700).
        parser.error(f"{LOCAL_PROCESSES} {args.local_processes}: more than this host's {cores} cores, one a process")


def listed_gpus(listing: str) -> int:
    """How many GPUs `nvidia-smi -L` lists in `listing`, its output: a line "GPU i: NAME (UUID: ...)" each (MIG
    instances are listed indented under their GPU)."""
    return sum(line.startswith("GPU ") for line in listing.splitlines())


def visible_gpus(listed: int, cuda_visible_devices: str | None, jax_platforms: str | None) -> int:
    """How many of the `listed` GPUs a JAX process started here uses. CUDA_VISIBLE_DEVICES, where set, names
    them ("" none), up to its first entry that is neither an index below `listed` nor a UUID, as CUDA reads it
    ("-1" hides all); JAX_PLATFORMS set without "cuda" (or "gpu") uses none."""
    if jax_platforms and not {"cuda", "gpu"} & {name.strip() for name in jax_platforms.split(",")}:
        return 0
    if cuda_visible_devices is None:
        return listed
    entries = (entry.strip() for entry in cuda_visible_devices.split(","))
    valid = itertools.takewhile(
        lambda entry: entry.startswith(("GPU-", "MIG-")) or (entry.isdigit() and int(entry) < listed), entries
    )
    return min(listed, sum(1 for _ in valid))


def nvidia_smi_listing() -> str:
    """`nvidia-smi -L`'s output; "" where the tool is missing or fails."""
    try:
        return subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True, timeout=60, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return ""


def gpus_here() -> int:
    """The GPUs a JAX process started on this host would use, counted without starting JAX."""
    listed = listed_gpus(nvidia_smi_listing())
    return visible_gpus(listed, os.environ.get("CUDA_VISIBLE_DEVICES"), os.environ.get("JAX_PLATFORMS"))


def steps_on_warp(env_kwargs: Mapping, warp_installed: bool) -> bool:
    """Whether an env built with `env_kwargs` steps MJX Warp on a GPU: "impl" is "warp", or "auto" with warp-lang
    installed (`warp_installed`); envs without MJX have no "impl"."""
    impl = env_kwargs.get("impl", Impl.JAX)
    return impl == Impl.WARP or (impl == Impl.AUTO and warp_installed)


def local_process_count(given: int | None, joined: bool, spreads: bool, gpus: int) -> int:
    """How many processes of a run to start on this host; 1: the command runs in its own process, driving every
    GPU it sees.

    `given` (`--local-processes`) where the command says; 1 where it is one of several already (`joined`:
    `--distributed`); else one per GPU (`gpus`) where the run gains from it (`spreads`: it steps MJX Warp, which
    scales better that way than in one process driving every GPU, BENCHMARKS.md#devices). MJX-JAX, and envs
    without MJX, scale about linearly in one process.
    """
    if given is not None:
        return given
    return gpus if spreads and not joined and gpus > 1 else 1


def join(args: argparse.Namespace) -> None:
    """Joins the other processes (`jax.distributed.initialize`) and opens the collectives between them
    (`open_collectives`); ValueError in one line where that fails.

    JAX's preemption service is left off: it sets a C++ SIGTERM handler that only records the signal for sync
    points this code never asks about, so a SIGTERM between joining and the chunk loop was lost (a joined process
    lived on after it, measured), and a local process whose launcher died then would train on alone. It also logs
    a warning and an error of its own as the coordination service goes."""
    jax.config.update("jax_enable_preemption_service", False)
    timeout = JOIN_TIMEOUT_S if args.join_timeout is None else args.join_timeout
    # JAX waits in C++, the GIL released: a timer thread can still end the process first, in one line.
    watchdog = threading.Timer(timeout, never_joined, (args, timeout))
    watchdog.daemon = True
    watchdog.start()
    try:
        jax.distributed.initialize(
            coordinator_address=args.coordinator,
            num_processes=args.num_processes,
            process_id=args.process_id,
            initialization_timeout=int(timeout) + JAX_DEADLINE_AFTER_S,
            shutdown_timeout_seconds=WAIT_FOR_PEERS_S,
        )
    except (ValueError, RuntimeError) as error:
        raise ValueError(
            f"--distributed could not join the other processes ({first_line(error)}); outside SLURM give --coordinator "
            "HOST:PORT, --num-processes N and --process-id I"
        ) from None
    finally:
        watchdog.cancel()
    atexit.register(shut_down)
    open_collectives()


def never_joined(args: argparse.Namespace, timeout: float) -> NoReturn:
    """Ends this process with one line (rc 2) where the others have not all joined within `timeout` seconds."""
    who = "" if args.process_id is None else f"process {args.process_id} of {args.num_processes}, "
    where = "" if args.coordinator is None else f"coordinator {args.coordinator}, "
    print(
        f"error: --distributed: not every process joined within {timeout:.0f} s ({who}{where}nothing trained); "
        "start the same command in each process, or give --join-timeout more seconds",
        file=sys.stderr,
        flush=True,
    )
    os._exit(2)


def open_collectives() -> None:
    """Opens the connections of the collectives between the processes once all have come here (a barrier of JAX's
    coordination service, which waits WAIT_FOR_PEERS_S). JAX would open them at the first collective, where gloo
    (the CPU's) gives the other processes 30 s to come: a process still compiling on a loaded CPU came later, and
    the first failed ("Gloo context initialization failed: ... GetKeyValue() timed out", a sweep of 2 processes on
    2 cores at load 6). Once open, a collective waited 60 s for a late peer there and went on. Gloo's line on
    opening them ("[Gloo] Rank 0 is connected to 1 peer ranks ...", on the C++ stdout) is kept off the console."""
    client = jax_distributed.global_state.client  # JAX has no public word for its barrier
    assert client is not None, "open_collectives follows jax.distributed.initialize"
    client.wait_at_barrier("jaxarm: collectives", WAIT_FOR_PEERS_S * 1000)
    with c_output_hidden(1):
        multihost_utils.sync_global_devices("jaxarm: collectives")


@contextlib.contextmanager
def c_output_hidden(fd: int):
    """Sends what C and C++ libraries write to file descriptor `fd` (1: stdout, 2: stderr) to /dev/null inside the
    block; Python's streams are flushed on both sides."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved, fd)
        os.close(saved)


def free_port() -> int:
    """A TCP port on this host that nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def without_local_processes(argv: Sequence[str]) -> list[str]:
    """`argv` less `--local-processes N` (or `--local-processes=N`)."""
    kept: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg == LOCAL_PROCESSES:
            skip = True
        elif not arg.startswith(LOCAL_PROCESSES + "="):
            kept.append(arg)
    return kept


def local_gpus(count: int) -> list[str]:
    """The GPU each of `count` local processes sees: the first `count` of CUDA_VISIBLE_DEVICES (default 0 …);
    ValueError where fewer are visible."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    gpus = [gpu for gpu in visible.split(",") if gpu] if visible is not None else [str(i) for i in range(count)]
    if len(gpus) < count:
        raise ValueError(f"{LOCAL_PROCESSES} {count}: CUDA_VISIBLE_DEVICES={visible} names only {len(gpus)}")
    return gpus[:count]


def spawn(main: Callable[[list[str]], int], argv: Sequence[str], count: int, resume: str = "") -> int:
    """Runs `main(ARGV)` as `count` processes of one job on this host (process i sees the i-th GPU) and waits for
    them. SIGINT and SIGTERM are passed on once to every process (each checkpoints and stops); where one fails, the
    others get SIGTERM, and SIGKILL after STOP_GRACE_S (a process waiting in a collective for a dead peer never
    reaches its checkpoint); where one dies of a signal (killed), one line names it and ends with `resume` (the
    command that continues the job). Should this process die, each of them gets SIGTERM (`_die_with_parent`).
    Returns the exit code of the first that failed (128 + N for one killed by signal N), else 0.

    The processes are forked from this one, so they start with its imports done (jax, MuJoCo, Warp: 6 s of each
    process's start on a GPU host). JAX must not have started its backend here (RuntimeError): a forked process
    cannot use the devices its parent opened."""
    # JAX has no public word for it; its own fork hook asks the same.
    if xla_bridge.backends_are_initialized():
        raise RuntimeError("distributed.spawn forks its processes: call it before JAX starts its backend")
    gpus = local_gpus(count)
    coordinator = f"127.0.0.1:{free_port()}"
    base = [
        *without_local_processes(argv),
        "--distributed",
        "--coordinator",
        coordinator,
        "--num-processes",
        str(count),
    ]
    sys.stdout.flush()
    sys.stderr.flush()  # else each process would write again what this one had buffered
    _peer_failed[0] = 0
    children = []
    launcher = os.getpid()
    for index, gpu in enumerate(gpus):
        pid = os.fork()
        if pid == 0:
            _run_forked(main, [*base, "--process-id", str(index)], gpu, launcher)
        children.append(pid)
    return _wait(children, resume)


def _wait(children: list[int], resume: str) -> int:
    """Waits for the processes `children` as `spawn` says: SIGINT and SIGTERM passed on once, the others stopped
    where one fails. Returns the exit code of the first that failed (`_failure`), else 0; the line that names it
    comes once every process has ended, after what they print as they go (a process that lost process 0 ends in
    JAX's abort, a block of C++ logs)."""
    codes: dict[int, int] = {}

    def forward(signum, frame):
        for pid in children:
            if pid not in codes:
                os.kill(pid, signum)

    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, forward)
    failed_at, failure, line = None, 0, None
    while len(codes) < len(children):
        for pid in children:
            if pid not in codes:
                done, status = os.waitpid(pid, os.WNOHANG)
                if done:
                    codes[pid] = os.waitstatus_to_exitcode(status)
        if failed_at is None and any(code != 0 for code in codes.values()):
            failed_at = time.monotonic()
            failure, line = _failure(children, codes, resume)
            _peer_failed[0] = 1
            forward(signal.SIGTERM, None)
        if failed_at is not None and time.monotonic() - failed_at > STOP_GRACE_S:
            forward(signal.SIGKILL, None)
        time.sleep(POLL_S)
    if line:
        print(line, file=sys.stderr, flush=True)
    return failure


def _failure(children: list[int], codes: dict[int, int], resume: str) -> tuple[int, str | None]:
    """The exit code of the first of `children` to fail (`codes`: those ended so far), 128 + N for one killed by
    signal N, and for that one a line that names it, ending with `resume`."""
    failure = next(code for code in codes.values() if code != 0)
    killed = [(children.index(pid), pid, -code) for pid, code in codes.items() if code < 0]
    if REPORTED_ERROR in codes.values() and all(number == signal.SIGABRT for *_, number in killed):
        # JAX aborts a process whose coordination service left with the peer that hosted it: here a peer that
        # stopped on an error it reported and waited REPORT_GRACE_S for the others in vain. That error is the
        # failure (2-core CPU, before that wait: 1 of 2 CI runs reported the abort instead).
        return REPORTED_ERROR, None
    if not killed:
        return failure, None
    index, pid, number = killed[0]
    return 128 + number, (
        f"error: process {index} (pid {pid}) was killed by {signal.Signals(number).name}; the others are told to "
        f"stop{f'; continue with: {resume}' if resume else ''}"
    )


def _die_with_parent(launcher: int) -> None:
    """Has the kernel send this forked process SIGTERM when its launcher dies (SIGKILL included), so that it
    checkpoints and stops rather than train on alone (Linux; elsewhere nothing). A launcher already gone: SIGTERM
    at once."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != launcher:
        os.kill(os.getpid(), signal.SIGTERM)


def first_line(error: BaseException) -> str:
    """The first line of `error`'s message (JAX's run to dozens), at most 200 characters; its type where empty."""
    text = str(error).strip()
    return text.splitlines()[0][:200] if text else type(error).__name__


def stopped_for_a_failed_peer() -> bool:
    """Whether this process's launcher (`spawn`) has told the job's processes to stop because one of them failed:
    the launcher's own line then says which, and how to go on."""
    return _peer_failed[0] == 1


def peer_lost_message(error: BaseException, index: int, resume: str) -> str | None:
    """One line for process `index` stopped by `error`, where JAX's words say its peers have gone (`PEER_LOST`);
    None for any other error."""
    text = str(error)
    if not any(words in text for words in PEER_LOST):
        return None
    return (
        f"error: process {index} stopped: another process of the job has gone ({type(error).__name__}: "
        f"{first_line(error)}){f'; continue with: {resume}' if resume else ''}"
    )


def leave_if_peers_lost(error: BaseException, resume: str) -> None:
    """Ends this process of a job in one line where `error` says its peers have gone (`peer_lost_message`), ending
    with `resume`: at once (`_leave`, exit status 1), as JAX's exit hook would wait for the gone peers at its
    shutdown barrier. Returns where `error` says something else, or this process joined no job."""
    message = peer_lost_message(error, jax.process_index(), resume) if joined() else None
    if message is not None:
        # Deaf before the line, not after: the launcher's SIGTERM, sent as this peer's death was seen, arrived
        # between the two and was reported as a second, "interrupted:" line (2-core CI, 1 run).
        ignore_stop_signals()
        print(message, file=sys.stderr)
        _leave(1)


def joined() -> bool:
    """Whether this process has joined others (`join`)."""
    return jax_distributed.global_state.client is not None


def _run_forked(main: Callable[[list[str]], int], argv: list[str], gpu: str, launcher: int) -> NoReturn:
    """The body of one forked process: `main(argv)` on GPU `gpu`, then out at once with its exit code.

    SIGTERM is a Ctrl-C here, whenever it comes: during training the chunk loop takes both as a request to stop at
    the next chunk end (jaxarm.runner.signals), outside it `main` ends on KeyboardInterrupt in one line. Left to
    its default, a SIGTERM after the loop (the final evaluation) ended the process without a word; the launcher
    sends it on, and its death sends one per launcher thread it passes through (1-3 with two extra threads)."""
    code = 1
    try:
        # Its own process group: a Ctrl-C at the terminal reaches the launcher alone, which passes it on once (a
        # second SIGINT would make each process exit without its checkpoint).
        os.setpgid(0, 0)
        for stream in (sys.stdout, sys.stderr):
            one_write_per_line(stream)
        signal.signal(signal.SIGTERM, signal.default_int_handler)
        _die_with_parent(launcher)
        os.environ["CUDA_VISIBLE_DEVICES"] = gpu
        code = main(argv)
    except SystemExit as exit_:
        code = exit_code(exit_.code)
    except KeyboardInterrupt:  # before `main` began: nothing started yet to report
        code = STOPPED_BY_SIGNAL
    except BaseException:
        traceback.print_exc()
    finally:
        _leave(code)


def one_write_per_line(stream) -> None:
    """Makes `stream` (a text stream over a file) write each line whole in one write, as processes sharing one
    terminal or pipe need: where Python writes through (PYTHONUNBUFFERED=1), `print` writes a line's text and its end
    apart, and two processes' errors came out as one line, "...split overerror: ...split over", then two ends."""
    if isinstance(stream, io.TextIOWrapper):
        stream.reconfigure(write_through=False, line_buffering=True)


def exit_code(code: object) -> int:
    """The exit status `sys.exit(code)` gives a process: 0 for None, the int, else 1 (after printing `code`)."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


REPORTED_ERROR = 2
"""The exit status of a command that stopped on an error it reported in one line (`experiments.run`)."""
ENDED_TOGETHER = (0, STOPPED_BY_SIGNAL)
"""Exit statuses of a process that ended where every process of its job ends: finished, or stopped at a chunk end
all agreed on (a signal passed on to all). Such a process waits for the others at JAX's shutdown barrier."""


def _leave(code: int) -> NoReturn:
    """Ends a forked process once the others have reached their end too (`shut_down`), without the interpreter's
    teardown: JAX's own exit hook collects garbage four times and closes every device before that barrier, and
    nothing of this process is left to write (a 4-GPU sorter run's processes took ~5 s from their last output to
    their exit, ~1 s this way; H200s, 2026-11-27). A failed process leaves at once: its peers may have gone, and
    the barrier would wait for them. A stopped one waits too: process 0, gone first, took JAX's coordination
    service with it, and JAX aborted process 1 with a block of C++ logs (launcher killed, 1 of 2 loaded runs). One
    that reported an error waits for the others to report theirs (`others_reported`) for the same reason."""
    ignore_stop_signals()
    sys.stdout.flush()
    sys.stderr.flush()
    if code in ENDED_TOGETHER or (code == REPORTED_ERROR and others_reported(REPORT_GRACE_S)):
        shut_down()
    os._exit(code)


def ignore_stop_signals_in_a_job(args: argparse.Namespace) -> None:
    """Makes a process of a job (`--distributed`) deaf to Ctrl-C and SIGTERM before it says why it ends: its
    launcher sends every process SIGTERM as one fails, and taken as a Ctrl-C it became a second line,
    "interrupted: ...", or another exit status. A process alone stays stoppable by hand through its exit."""
    if args.distributed:
        ignore_stop_signals()


def ignore_stop_signals() -> None:
    """Said and done: a Ctrl-C or SIGTERM from here (the launcher stopping the others as one fails) would raise
    in the barrier's wait and out of `_run_forked`, into the launcher's code this process was forked from."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)


def others_reported(timeout_s: float) -> bool:
    """Whether every process of the job came, within `timeout_s`, to where it stops on an error it reported (a
    barrier of JAX's coordination service): an error of the config or of the run directory, which every process
    meets, one later than another. False where this process joined no job, or one of the others is still running
    (in a collective, waiting for this one) or has gone."""
    client = jax_distributed.global_state.client
    if client is None:
        return False
    try:
        with c_output_hidden(2):  # the service's error block naming the processes that did not come
            client.wait_at_barrier("jaxarm: reported errors", int(timeout_s * 1000))
    except jax.errors.JaxRuntimeError:
        return False
    return True


def shut_down() -> None:
    """Leaves the job once every process has come to its end (`jax.distributed.shutdown`'s barrier), in one line
    where that fails: a process that came there has written what it had to. What JAX and gRPC print meanwhile
    is kept off the console: the tasks' teardown as process 0 stops the coordination service ("WatchTasksAsync
    failed ... Connection refused", 4 H200s), or the barrier's own error block. Registered by `join` to run at exit
    before JAX's own hook, which would shut down again, but without the line."""
    try:
        with c_output_hidden(2):
            jax.distributed.shutdown()
    except Exception as error:  # a peer that died first: leave anyway
        print(
            f"note: JAX could not shut this process down cleanly ({first_line(error)}); what it wrote is kept",
            file=sys.stderr,
        )
