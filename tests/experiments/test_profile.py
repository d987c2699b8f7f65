"""The profile suite books each op to the learner phase its name stack names, counting nested ops once."""

import json
import types

import pytest

from experiments import configs
from experiments.benchmarks import profile
from jaxarm.agents.common.config import apply_overrides

PHASES = ("collect", "advantages", "sgd")


def test_name_stacks_map_to_whole_scopes_only():
    assert profile.phase_of("jit(run_updates)/while/body/closed_call/sgd/while/body/add", PHASES) == "sgd"
    assert profile.phase_of("jit(run_updates)/while/body/collect/vmap()/step", PHASES) == "collect"
    assert profile.phase_of("jit(run_updates)/while/body/sgd_like/add", PHASES) == profile.UNATTRIBUTED
    # A scope opened inside a vmap is named `vmap(scope)` in the stack.
    assert profile.phase_of("jit(run_updates)/while/body/collect/vmap(sgd)/add", ("sgd", "collect")) == "sgd"
    assert profile.phase_of("jit(run_updates)/jvp(vmap(sgd_like))/add", PHASES) == profile.UNATTRIBUTED
    assert profile.phase_of("", PHASES) == profile.UNATTRIBUTED


def test_instruction_names_are_read_with_their_name_stacks():
    hlo = (
        "  %fusion.3 = f32[64]{0} fusion(f32[64]{0} %p), kind=kLoop, calls=%fused, "
        'metadata={op_type="add" op_name="jit(f)/sgd/add" source_file="x.py"}\n'
        "  ROOT %copy.1 = f32[64]{0} copy(f32[64]{0} %fusion.3)\n"
        '  %wrapped_sine = f32[64]{0} fusion(%p), metadata={op_name="jit(f)/collect/sin"}\n'
    )
    assert profile.op_names(hlo) == {"fusion.3": "jit(f)/sgd/add", "wrapped_sine": "jit(f)/collect/sin"}


def test_only_innermost_events_count():
    def event(start, duration):
        return types.SimpleNamespace(start_ns=start, duration_ns=duration)

    loop, body_a, body_b, after = event(0, 100), event(10, 20), event(40, 50), event(100, 5)
    assert profile.leaf_events([after, body_b, loop, body_a]) == [body_a, body_b, after]
    assert profile.leaf_events([]) == []  # a profile line with no XLA ops


def test_a_small_ppo_run_books_time_to_every_phase():
    config = apply_overrides(configs.get("ppo_arm2d"), ["num_envs=64", "rollout_length=8", "num_minibatches=2"])
    wall, times = profile.profile_updates(config, num_updates=2, phases=PHASES)
    by_phase = {time.phase: time for time in times}
    assert wall > 0
    assert list(by_phase) == [*PHASES, profile.UNATTRIBUTED]
    for phase in PHASES:
        assert by_phase[phase].ops > 0 and by_phase[phase].seconds > 0, phase
    table = profile.format_table(wall, times, num_updates=2)
    assert "| sgd |" in table and "| wall clock |" in table


@pytest.mark.slow
def test_suite_writes_its_phases(capsys, tmp_path):
    argv = ["--updates", "1", "--out", str(tmp_path), "num_envs=16", "rollout_length=4", "num_minibatches=2"]
    profile.main(argv)
    out = capsys.readouterr().out
    written = json.loads((tmp_path / "profile.json").read_text())
    assert [row["phase"] for row in written["rows"]] == [*PHASES, profile.UNATTRIBUTED]
    assert written["overrides"] == ["num_envs=16", "rollout_length=4", "num_minibatches=2"]
    assert written["wall_ms_per_update"] > 0
    sgd = written["rows"][PHASES.index("sgd")]
    assert f"| sgd | {sgd['busy_ms_per_update']:.2f} |" in out
