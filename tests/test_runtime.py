"""jaxarm's process-wide XLA:CPU setting for MJX, and the per-program options that undo it elsewhere."""

from jaxarm import _runtime


def test_cpu_flag_only_for_jaxlib_0_10_and_never_over_the_users_choice():
    assert _runtime.cpu_flag_wanted((0, 10), "", keep_flags=False)
    assert not _runtime.cpu_flag_wanted((0, 11), "", keep_flags=False)
    assert not _runtime.cpu_flag_wanted((0, 10), "--xla_cpu_use_fusion_emitters=true", keep_flags=False)
    assert not _runtime.cpu_flag_wanted((0, 10), "", keep_flags=True)


def test_programs_without_mjx_turn_the_fusion_emitters_back_on_only_where_jaxarm_turned_them_off():
    assert _runtime.fusion_emitter_options(flag_applied=True, uses_mjx=False) == {
        "xla_cpu_use_fusion_emitters": True}
    assert _runtime.fusion_emitter_options(flag_applied=True, uses_mjx=True) == {}
    assert _runtime.fusion_emitter_options(flag_applied=False, uses_mjx=False) == {}
