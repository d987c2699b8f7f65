"""Which MJX implementation steps a Panda scene ("jax" or "warp"), and the buffers Warp needs sized for it.

mujoco-mjx 3.17 runs the same mjx.Model / mjx.Data API on two implementations: JAX (`"jax"`, any device;
contact arrays hold every contact each explicit pair could make, so nothing can overflow) and NVIDIA's Warp
(`"warp"`, needs warp-lang and a CUDA GPU or the CPU). Warp keeps the contacts of every env of a batch in one
buffer of `naconmax` rows and each env's constraint rows in `njmax`; both are fixed when the data is made,
and a step that needs more drops what does not fit and sets a bit of the env's overflow word. Here both are
sized for the scene's worst case (`contact_capacity`, `constraint_capacity`), and `check_no_overflow` turns
a set bit into an error instead of a silently different simulation (or, while steps are traced under
`deferred_step_checks`, leaves the task to record `overflow_bits` for `raise_on_overflow` after a rollout).
Warp also poses the geoms of bodies fixed to the world once, when the data is made, so a task that moves them
per env (the peg's block) has them posed again from the episode's model by `pose_fixed_geoms`.

Nothing here knows about a task: it reads only the MjModel and the mjx.Model / mjx.Data it is given.
"""

import enum

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from jax.experimental import io_callback
from mujoco import mjx
from mujoco.mjx import warp as mjx_warp
from mujoco.mjx._src import math as mjx_math

from jaxarm.envs.base import step_checks_deferred


class Impl(enum.StrEnum):
    """An MJX implementation to step the physics with."""

    JAX = "jax"
    WARP = "warp"
    AUTO = "auto"
    """Warp on an NVIDIA GPU when warp-lang is importable, JAX otherwise."""


_GEOM = mujoco.mjtGeom
PAIR_MAX_CONTACTS = {
    frozenset([_GEOM.mjGEOM_BOX]): 8,
    frozenset([_GEOM.mjGEOM_PLANE, _GEOM.mjGEOM_BOX]): 8,
    frozenset([_GEOM.mjGEOM_PLANE, _GEOM.mjGEOM_CAPSULE]): 2,
    frozenset([_GEOM.mjGEOM_CAPSULE]): 2,
    frozenset([_GEOM.mjGEOM_CAPSULE, _GEOM.mjGEOM_BOX]): 2,
}
"""Most contacts MuJoCo Warp's primitive collision of two geom types emits (collision_primitive_core.py: box-box
and plane-box return 8, anything with a capsule but no sphere 2). Pairs with a sphere emit one; other types
go through the convex (GJK) path, bounded by mujoco.mjMAXCONPAIR."""
_BUFFER_OVERFLOWS = (
    mjx_warp.mjwp_types.OverflowType.NEFC
    | mjx_warp.mjwp_types.OverflowType.NJMAX_NNZ
    | mjx_warp.mjwp_types.OverflowType.BROADPHASE
    | mjx_warp.mjwp_types.OverflowType.NARROWPHASE
    | mjx_warp.mjwp_types.OverflowType.CCD
    if mjx_warp.WARP_INSTALLED
    else 0
)
"""The overflow bits that mean dropped contacts or constraint rows (the solver's iteration-limit bits do not:
the Panda scenes run 4 Newton iterations by design)."""


def warp_available() -> bool:
    """Whether MJX can use Warp here (warp-lang imported)."""
    return bool(mjx_warp.WARP_INSTALLED)


def _cuda_devices() -> list[jax.Device]:
    try:
        return jax.devices("cuda")
    except RuntimeError:  # no CUDA backend in this jaxlib
        return []


def resolve_impl(impl: str) -> Impl:
    """`impl` ("jax", "warp" or "auto") -> the implementation to use; a clear error where Warp cannot run."""
    try:
        chosen = Impl(impl)
    except ValueError:
        raise ValueError(f"impl must be one of {[i.value for i in Impl]}, got {impl!r}") from None
    device = jax.devices()[0]
    on_nvidia_gpu = device in _cuda_devices()
    if chosen == Impl.AUTO:
        return Impl.WARP if warp_available() and on_nvidia_gpu else Impl.JAX
    if chosen == Impl.WARP:
        if not warp_available():
            raise ValueError("impl='warp' needs warp-lang (pip install -e '.[warp]'); use impl='jax' without it")
        if not (on_nvidia_gpu or device.platform == "cpu"):
            raise ValueError(f"impl='warp' runs on a CUDA GPU or the CPU, but JAX's default device is {device}")
    return chosen


def pair_max_contacts(type1: int, type2: int) -> int:
    """Most contacts one explicit pair of these two geom types can emit in one collision pass."""
    types = frozenset([_GEOM(type1), _GEOM(type2)])
    if _GEOM.mjGEOM_SPHERE in types:
        return 1
    return PAIR_MAX_CONTACTS.get(types, mujoco.mjMAXCONPAIR)


def contact_capacity(mj_model: mujoco.MjModel) -> int:
    """Most contacts one env of the scene can have at once: every explicit pair at its types' maximum.

    Raises ValueError if any geom collides outside the explicit pairs (the Panda scenes allow none).
    """
    if np.any(mj_model.geom_contype) or np.any(mj_model.geom_conaffinity):
        raise ValueError("contact capacity is bounded only for scenes whose contacts all come from explicit <pair>s")
    types = mj_model.geom_type
    return sum(
        pair_max_contacts(types[g1], types[g2]) for g1, g2 in zip(mj_model.pair_geom1, mj_model.pair_geom2, strict=True)
    )


def _rows_per_contact(mj_model: mujoco.MjModel) -> np.ndarray:
    """[npair] constraint rows one contact of each pair takes: condim with an elliptic cone; 1 for condim 1,
    else 2 (condim − 1) with a pyramidal one."""
    condim = mj_model.pair_dim
    if mj_model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL:
        return np.where(condim == 1, 1, 2 * (condim - 1))
    return condim


def constraint_capacity(mj_model: mujoco.MjModel, contacts: int | None = None) -> int:
    """Most constraint rows one env of the scene can have: its contacts' rows, one row per limited joint and
    tendon, per dof and tendon with friction loss, and every equality's rows. The contacts are every pair's at
    its types' maximum, or, given `contacts`, that many of the pairs' costliest kind."""
    types = mj_model.geom_type
    rows = _rows_per_contact(mj_model)
    if contacts is None:
        contact_rows = sum(
            pair_max_contacts(types[g1], types[g2]) * pair_rows
            for g1, g2, pair_rows in zip(mj_model.pair_geom1, mj_model.pair_geom2, rows, strict=True)
        )
    else:
        contact_rows = contacts * int(np.max(rows, initial=0))
    equality_rows = {
        mujoco.mjtEq.mjEQ_CONNECT: 3,
        mujoco.mjtEq.mjEQ_WELD: 6,
    }
    eq_rows = sum(equality_rows.get(mujoco.mjtEq(t), 1) for t in mj_model.eq_type)
    return int(
        contact_rows
        + eq_rows
        + np.sum(mj_model.jnt_limited)
        + np.sum(mj_model.tendon_limited)
        + np.sum(mj_model.dof_frictionloss > 0)
        + np.sum(mj_model.tendon_frictionloss > 0)
    )


def put_scene(
    mj_model: mujoco.MjModel, impl: Impl, max_envs: int, contacts_per_env: int | None = None
) -> tuple[mjx.Model, mjx.Data]:
    """(mjx.Model, initial mjx.Data) of the scene for `impl`. Warp's contact buffer (shared by a batch) holds
    `contacts_per_env` contacts (default: the scene's worst case, `contact_capacity`) for each of `max_envs`
    envs, and each env's constraint rows the rows of that many contacts (`constraint_capacity`).

    Both live on this process's first device: MJX's default, `jax.devices()[0]`, is process 0's device in every
    process of a run of several (`--distributed`), where no other process's program may close over them. On a
    CUDA GPU, Warp's kernels for the scene start compiling in the background (`warp_kernels.start_preload`), and
    Warp's wrappers of JAX's stream are counted (`warp_streams`)."""
    device = jax.local_devices()[0]
    if impl == Impl.JAX:
        return mjx.put_model(mj_model, device, impl="jax"), mjx.make_data(mj_model, device, impl="jax")
    if contacts_per_env is not None and contacts_per_env < 1:
        raise ValueError(f"contacts_per_env must be at least 1, got {contacts_per_env}")
    model = without_graph_conditionals(silence_overflow_warnings(mjx.put_model(mj_model, device, impl="warp")))
    data = mjx.make_data(
        mj_model,
        device,
        impl="warp",
        naconmax=(contacts_per_env or contact_capacity(mj_model)) * max_envs,
        njmax=constraint_capacity(mj_model, contacts_per_env),
    )
    if device in _cuda_devices():
        from jaxarm.envs.panda import warp_kernels, warp_streams  # import warp: only where Warp steps

        warp_streams.count_foreign_stream_wrappers()
        warp_kernels.start_preload(mj_model, f"cuda:{device.local_hardware_id}")
    return model, data


def silence_overflow_warnings(model: mjx.Model) -> mjx.Model:
    """Warp `model` whose kernels print no overflow warnings (they still set the overflow bits).

    By default every Warp world prints a line from the GPU whenever its solver stops at its iteration limit,
    which the Panda scenes' 4 Newton iterations reach by design: thousands of lines per substep in training.
    Without them a ppo_sorter update (8,192 envs x 16 steps, H100) took 289 ms instead of 393. The bits
    that matter, dropped contacts or constraint rows, still raise in `check_no_overflow`.
    """
    options = model.opt._impl.replace(warn_overflow=0)  # type: ignore[union-attr]  # Warp's own Option fields
    return model.replace(opt=model.opt.replace(_impl=options))


def without_graph_conditionals(model: mjx.Model) -> mjx.Model:
    """Warp `model` whose solver runs its `iterations` in a plain loop, not in a CUDA graph conditional node.

    mujoco_warp loops its Newton iterations in a conditional node that ends once every world has converged; the
    Panda scenes' 4 iterations seldom end it early. In a plain loop, worlds that have converged skip the rest
    inside the kernels. A ppo_sorter update at 2,048 envs took 172.7 ms against 175.9 (H200, means of six
    timings from two processes each), and 512 envs stepped 60 times from one state differ from the conditional
    loop's no more than two runs of either differ from each other (Warp's float atomics vary the last bits).
    """
    options = model.opt._impl.replace(graph_conditional=False)  # type: ignore[union-attr]  # Warp's own Option
    return model.replace(opt=model.opt.replace(_impl=options))


def with_geom_sizes(model: mjx.Model, geom_ids: np.ndarray, size: jax.Array, rbound: jax.Array) -> mjx.Model:
    """`model` with geoms `geom_ids` [G] resized to `size` [G, 3] and bounding radius `rbound` [G], and their
    (centred) bounding boxes to match: Warp's broadphase culls pairs by both, JAX's reads neither."""
    types = np.asarray(model.geom_type)[geom_ids]
    radius, second = size[:, :1], size[:, 1:2]
    half_extent = jnp.select(
        [
            jnp.asarray(types == _GEOM.mjGEOM_SPHERE)[:, None],
            jnp.asarray(types == _GEOM.mjGEOM_CAPSULE)[:, None],
            jnp.asarray(types == _GEOM.mjGEOM_CYLINDER)[:, None],
        ],
        [
            jnp.tile(radius, 3),
            jnp.concatenate([radius, radius, radius + second], -1),
            jnp.concatenate([radius, radius, second], -1),
        ],
        size,
    )
    aabb = jnp.asarray(model.geom_aabb)
    aabb = aabb.reshape(-1, 2, 3).at[geom_ids, 1].set(half_extent).reshape(aabb.shape)
    return model.replace(
        geom_size=model.geom_size.at[geom_ids].set(size),
        geom_rbound=model.geom_rbound.at[geom_ids].set(rbound),
        geom_aabb=aabb,
    )


def pose_fixed_geoms(mj_model: mujoco.MjModel, model: mjx.Model, data: mjx.Data) -> mjx.Data:
    """`data` with the bodies fixed to the world, and their geoms, posed from `model` (whose body_pos,
    geom_pos... may be this env's). Warp's kinematics skips them after make_data; JAX's already poses them."""
    xpos, xquat = data.xpos, data.xquat
    fixed_bodies = np.flatnonzero(mj_model.body_weldid[1:] == 0) + 1
    for body in fixed_bodies:  # parents come before their children
        parent = mj_model.body_parentid[body]
        xpos = xpos.at[body].set(xpos[parent] + mjx_math.rotate(model.body_pos[body], xquat[parent]))
        xquat = xquat.at[body].set(mjx_math.quat_mul(xquat[parent], model.body_quat[body]))
    body_of = mj_model.geom_bodyid
    geoms = np.flatnonzero(mj_model.body_weldid[body_of] == 0)
    geom_xquat = jax.vmap(mjx_math.quat_mul)(xquat[body_of[geoms]], model.geom_quat[geoms])
    return data.replace(
        xpos=xpos,
        xquat=xquat,
        xmat=data.xmat.at[fixed_bodies].set(jax.vmap(mjx_math.quat_to_mat)(xquat[fixed_bodies])),
        geom_xpos=data.geom_xpos.at[geoms].set(
            xpos[body_of[geoms]] + jax.vmap(mjx_math.rotate)(model.geom_pos[geoms], xquat[body_of[geoms]])
        ),
        geom_xmat=data.geom_xmat.at[geoms].set(jax.vmap(mjx_math.quat_to_mat)(geom_xquat)),
    )


def _raise_on_overflow(overflow: np.ndarray) -> None:
    """Host side of the overflow checks: raises if any of the [...] overflow words is set."""
    bits = sorted({int(word) for word in np.ravel(overflow) if word})
    if bits:
        raise RuntimeError(
            f"MJX Warp overflow (OverflowType bits {bits}): contacts or constraint rows were dropped; the "
            "buffers are too small for this batch: build the env with a larger max_envs"
        )


def _no_overflow(overflow: np.ndarray) -> np.ndarray:
    """Host side of `check_no_overflow`: [...] overflow words -> all True, or raises."""
    _raise_on_overflow(overflow)
    return np.ones(overflow.shape, np.bool_)


def overflow_bits(data: mjx.Data) -> jax.Array:
    """[] int32: the bits of `data`'s overflow word that mean dropped contacts or constraint rows, set by any
    Warp step since the data was made; 0 for JAX's data, which cannot overflow."""
    if data.impl != mjx.Impl.WARP:
        return jnp.zeros((), jnp.int32)
    return (data._impl.overflow & _BUFFER_OVERFLOWS).astype(jnp.int32)  # type: ignore[union-attr]  # Warp's own


def raise_on_overflow(overflow: jax.Array) -> None:
    """A RuntimeError when the jitted program runs if any of the overflow words `overflow` [...]
    (`overflow_bits`) is set: one host call for the whole batch, an effect that runs though nothing reads it."""
    io_callback(_raise_on_overflow, None, overflow)


def check_no_overflow(data: mjx.Data) -> mjx.Data:
    """`data`, once a Warp step since it was made is known to have dropped no contacts or constraint rows
    (a RuntimeError when the jitted program runs otherwise); JAX's data, which cannot overflow, as it is; and
    `data` unchecked while steps are traced under `deferred_step_checks`, whose caller raises on the bits the
    task recorded instead (`raise_on_overflow`).

    Warp ORs its overflow bits into the data in every step, so one check after a run of substeps covers them
    all. The check is one host call per batch (not per env), and qpos depends on its answer so that the step
    waits for it.
    """
    if data.impl != mjx.Impl.WARP or step_checks_deferred():
        return data
    overflow = overflow_bits(data)
    fine = jax.pure_callback(
        _no_overflow, jax.ShapeDtypeStruct(overflow.shape, jnp.bool_), overflow, vmap_method="expand_dims"
    )
    return data.replace(qpos=jnp.where(fine, data.qpos, jnp.nan))
