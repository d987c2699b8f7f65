"""jaxarm's process-wide XLA:CPU setting for MJX, and the per-program options that undo it elsewhere."""

import os
import subprocess
import sys

import pytest

from jaxarm import _runtime


def test_cpu_flag_only_for_jaxlib_0_10_and_never_over_the_users_choice():
    assert _runtime.cpu_flag_wanted((0, 10), "", keep_flags=False)
    assert not _runtime.cpu_flag_wanted((0, 11), "", keep_flags=False)
    assert not _runtime.cpu_flag_wanted((0, 10), "--xla_cpu_use_fusion_emitters=true", keep_flags=False)
    assert not _runtime.cpu_flag_wanted((0, 10), "", keep_flags=True)


def test_programs_without_mjx_turn_the_fusion_emitters_back_on_only_where_jaxarm_turned_them_off():
    assert _runtime.fusion_emitter_options(flag_applied=True, uses_mjx=False) == {"xla_cpu_use_fusion_emitters": True}
    assert _runtime.fusion_emitter_options(flag_applied=True, uses_mjx=True) == {}
    assert _runtime.fusion_emitter_options(flag_applied=False, uses_mjx=False) == {}


def test_the_flag_counts_as_jaxarms_in_a_child_only_with_the_marker():
    flag = "--xla_cpu_use_fusion_emitters=false"
    assert _runtime.cpu_flag_inherited(flag, "1", keep_flags=False)
    assert not _runtime.cpu_flag_inherited(flag, None, keep_flags=False)  # the user's own flag
    assert not _runtime.cpu_flag_inherited("", "1", keep_flags=False)
    assert not _runtime.cpu_flag_inherited(flag, "1", keep_flags=True)


def test_a_child_process_makes_its_parents_choice():
    # This process imported jaxarm (conftest); a subprocess inherits its environment, as a killed-and-resumed run's
    # does, and must compile every program alike.
    child = subprocess.run(
        [sys.executable, "-c", "import jaxarm._runtime as r; r.apply_xla_settings(); print(r._cpu_flag_applied)"],
        env=dict(os.environ),
        capture_output=True,
        text=True,
        check=True,
    )
    assert child.stdout.strip() == str(_runtime._cpu_flag_applied)


@pytest.mark.parametrize(
    "program",
    ["import experiments.configs, jaxarm.envs.panda_sort, jaxarm.envs.peg_insert", "import jaxarm.interop.brax_env"],
)
def test_importing_the_learners_mjx_envs_and_brax_adapter_prints_nothing(program):
    """mujoco-mjx prints "Failed to import warp" on import without warp-lang; every command started with it, and
    the brax adapter (brax imports mujoco.mjx) imported alone."""
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
