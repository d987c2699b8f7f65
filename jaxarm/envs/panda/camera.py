"""Depth and grayscale images of a MuJoCo scene, cast analytically in JAX (jit- and vmap-safe, CPU or GPU).

Every geom of our scenes is a primitive (plane, sphere, capsule, cylinder, box), so one ray per pixel is
intersected with each geom in closed form, in the geom's own frame; the nearest hit wins. Depth is the distance
along the camera's optical axis (as a depth camera reports it, not along the ray); grayscale is the geom's
rgba luma under a head light: ambient `AMBIENT` plus Lambert's cos between the surface normal and the ray.
A ray that hits nothing reads depth `FAR` and gray 0. Cameras are the MJCF's <camera>s with mode "fixed" (on
their body: a scene camera on the world, a hand camera on the hand); images are square, `fovy` both ways. A
`PoseOffset` moves a camera off its MJCF pose, in its own frame, as a real camera's mounting errs.

It reads poses (`geom_xpos`, `geom_xmat`, `xpos`, `xmat`) and sizes (`geom_size`, which a task may replace
per episode) as arrays, so it serves mjx.Data and, in tests, MuJoCo's own CPU data alike. It must stay free of
task logic: what an env observes of the images is the env's choice.
"""

import dataclasses
import functools
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxarm.deploy.camera import AMBIENT, LUMA  # declared there: the deployment loop draws the same images

FAR = 10.0
"""Depth, metres, of a ray that hits nothing."""
_EPSILON = 1e-9
_EXACT = jax.lax.Precision.HIGHEST
"""Float32 products for poses: a GPU's default TF32 moves a ray by ~1 mm per metre and flips edge pixels."""

Vector = tuple[jax.Array, jax.Array, jax.Array]
"""x, y and z components of a vector or of a batch of them (same shapes, or broadcastable)."""
Hit = tuple[jax.Array, jax.Array]
"""(distance along the ray, inf on a miss; |cos| of the angle between the ray and the surface's normal there)."""


def _safe(x: jax.Array) -> jax.Array:
    """x with exact zeros moved off zero, so that 1/x stays finite (the hit tests then reject the ray)."""
    return jnp.where(jnp.abs(x) < _EPSILON, _EPSILON, x)


def _ahead(t: jax.Array) -> jax.Array:
    """t where the hit lies ahead of the ray's origin, inf behind it."""
    return jnp.where(t > 0, t, jnp.inf)


def _nearer(first: Hit, second: Hit) -> Hit:
    """The nearer of two hits (or of two (distance, anything) pairs: `cast` keeps the brightness beside it)."""
    closer = second[0] < first[0]
    return jnp.where(closer, second[0], first[0]), jnp.where(closer, second[1], first[1])


def _ray_sphere(origin: Vector, direction: Vector, radius, centre_z=0.0) -> Hit:
    offset_z = origin[2] - centre_z
    b = origin[0] * direction[0] + origin[1] * direction[1] + offset_z * direction[2]
    disc = b * b - (origin[0] ** 2 + origin[1] ** 2 + offset_z**2 - radius * radius)
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    near, far = _ahead(-b - root), _ahead(-b + root)
    t = jnp.where(disc >= 0, jnp.minimum(near, far), jnp.inf)
    # The normal is (origin + t direction - centre) / radius, so its cos with the unit direction is (b + t) / radius.
    return t, jnp.abs(b + t) / radius


def _ray_tube(origin: Vector, direction: Vector, radius, half_length) -> Hit:
    """The side of a z-axis cylinder of `radius` between z = ±half_length (no caps)."""
    a = direction[0] ** 2 + direction[1] ** 2
    b = origin[0] * direction[0] + origin[1] * direction[1]
    disc = b * b - a * (origin[0] ** 2 + origin[1] ** 2 - radius * radius)
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    valid = (disc >= 0) & (a > _EPSILON)
    hits = []
    for t in ((-b - root) / _safe(a), (-b + root) / _safe(a)):
        inside = valid & (jnp.abs(origin[2] + t * direction[2]) <= half_length)
        hits.append(_ahead(jnp.where(inside, t, jnp.inf)))
    t = jnp.minimum(*hits)
    # The normal is the hit point's (x, y, 0) / radius: its cos with the direction is (b + t a) / radius.
    return t, jnp.abs(b + t * a) / radius


def ray_plane(origin: Vector, direction: Vector, size: jax.Array) -> Hit:
    """The hit of rays (local frame: origins, unit directions) on the plane z = 0 within its half extents
    size[0], size[1] (0: unbounded)."""
    t = -origin[2] / _safe(direction[2])
    within = t > 0
    for axis in (0, 1):
        within &= (size[axis] <= 0) | (jnp.abs(origin[axis] + t * direction[axis]) <= size[axis])
    return jnp.where(within, t, jnp.inf), jnp.abs(direction[2])


def ray_sphere(origin: Vector, direction: Vector, size: jax.Array) -> Hit:
    """As `ray_plane`, for a sphere of radius size[0]."""
    return _ray_sphere(origin, direction, size[0])


def ray_capsule(origin: Vector, direction: Vector, size: jax.Array) -> Hit:
    """As `ray_plane`, for a capsule of radius size[0] whose segment spans z = ±size[1]."""
    radius, half_length = size[0], size[1]
    hit = _ray_tube(origin, direction, radius, half_length)
    for centre_z in (half_length, -half_length):
        hit = _nearer(hit, _ray_sphere(origin, direction, radius, centre_z))
    return hit


def ray_cylinder(origin: Vector, direction: Vector, size: jax.Array) -> Hit:
    """As `ray_plane`, for a cylinder of radius size[0] spanning z = ±size[1]."""
    radius, half_length = size[0], size[1]
    hit = _ray_tube(origin, direction, radius, half_length)
    for z in (half_length, -half_length):
        t = (z - origin[2]) / _safe(direction[2])
        on_cap = (origin[0] + t * direction[0]) ** 2 + (origin[1] + t * direction[1]) ** 2 <= radius * radius
        hit = _nearer(hit, (_ahead(jnp.where(on_cap, t, jnp.inf)), jnp.abs(direction[2])))
    return hit


def ray_box(origin: Vector, direction: Vector, size: jax.Array) -> Hit:
    """As `ray_plane`, for a box of half sizes size[:3] (slab test)."""
    enters, leaves = [], []
    for axis in range(3):
        inverse = 1.0 / _safe(direction[axis])
        first, second = (-size[axis] - origin[axis]) * inverse, (size[axis] - origin[axis]) * inverse
        enters.append(jnp.minimum(first, second))
        leaves.append(jnp.maximum(first, second))
    enter = jnp.maximum(jnp.maximum(enters[0], enters[1]), enters[2])
    leave = jnp.minimum(jnp.minimum(leaves[0], leaves[1]), leaves[2])
    hit = (leave >= jnp.maximum(enter, 0.0)) & (leave > 0)
    from_outside = enter > 0
    # The face crossed is the axis whose slab the ray enters last (from outside) or leaves first (from inside).
    face = jnp.where(from_outside, enter, leave)
    cosine = jnp.where(
        face == jnp.where(from_outside, enters[0], leaves[0]),
        jnp.abs(direction[0]),
        jnp.where(face == jnp.where(from_outside, enters[1], leaves[1]), jnp.abs(direction[1]), jnp.abs(direction[2])),
    )
    return jnp.where(hit, face, jnp.inf), cosine


RayTest = Callable[[Vector, Vector, jax.Array], Hit]
"""A primitive's ray test: (origins, unit directions, size [3]) -> hit, all in the geom's frame."""

RAY_TESTS: dict[int, RayTest] = {
    mujoco.mjtGeom.mjGEOM_PLANE: ray_plane,
    mujoco.mjtGeom.mjGEOM_SPHERE: ray_sphere,
    mujoco.mjtGeom.mjGEOM_CAPSULE: ray_capsule,
    mujoco.mjtGeom.mjGEOM_CYLINDER: ray_cylinder,
    mujoco.mjtGeom.mjGEOM_BOX: ray_box,
}
"""Geom type -> its ray test. The tests are written per component, with no reductions, so that XLA fuses a
geom's work over every ray into one element-wise loop rather than kernels with [rays, geoms] arrays between them
(4-5x faster, BENCHMARKS.md)."""


@dataclasses.dataclass(frozen=True)
class Scene:
    """What the caster needs of a compiled model, resolved once outside jit.

    Attributes:
      geoms: ids [G] of the visible geoms (alpha > 0), each tested against every ray.
      types: their `mjtGeom` types, one per id.
      luma: [G] brightness of each one's rgba (Rec. 601 weights).
    """

    geoms: np.ndarray
    types: tuple[int, ...]
    luma: np.ndarray

    @property
    def groups(self) -> tuple[tuple[int, np.ndarray], ...]:
        """(type, indices into `geoms` [G_t]) for each type present, types in `RAY_TESTS`' order."""
        types = np.asarray(self.types)
        return tuple(
            (geom_type, np.flatnonzero(types == geom_type)) for geom_type in RAY_TESTS if np.any(types == geom_type)
        )

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> "Scene":
        """Every visible geom of `model`; ValueError naming a geom that is not a primitive."""
        visible = np.flatnonzero(model.geom_rgba[:, 3] > 0)
        types = tuple(int(model.geom_type[geom]) for geom in visible)
        for geom, geom_type in zip(visible, types, strict=True):
            if geom_type not in RAY_TESTS:
                kind = mujoco.mjtGeom(geom_type).name
                raise ValueError(f"geom {model.geom(geom).name or geom} is a {kind}: the camera casts primitives only")
        luma = model.geom_rgba[visible, :3] @ LUMA
        return cls(geoms=visible, types=types, luma=luma.astype(np.float32))


class PoseOffset(NamedTuple):
    """A rigid offset of a camera from its MJCF pose, in the camera's own frame: x right, y up in the image, z
    backwards (a camera looks along its −z).

    Attributes:
      shift: [3] metres the camera moves along its x, y and z axes (+z: away from what it sees).
      turn: [3] rotation vector (radians, right-hand rule) about its x, y and z axes, applied at its new position:
        +x pitches the view up, +y yaws it left, +z rolls the camera anticlockwise (the image turns clockwise).
    """

    shift: jax.Array | np.ndarray
    turn: jax.Array | np.ndarray


NO_OFFSET = PoseOffset(shift=np.zeros(3, np.float32), turn=np.zeros(3, np.float32))
"""The camera at its MJCF pose."""


def rotation_of(turn: jax.Array | np.ndarray) -> jax.Array:
    """[3, 3] rotation by the rotation vector `turn` [3] (Rodrigues' formula; exactly the identity for zeros)."""
    turn = jnp.asarray(turn, jnp.float32)
    angle = jnp.sqrt(jnp.sum(turn * turn))
    cross = jnp.array([[0.0, -turn[2], turn[1]], [turn[2], 0.0, -turn[0]], [-turn[1], turn[0], 0.0]], jnp.float32)
    # sin(a)/a and (1 - cos(a))/a² through sinc, finite at a = 0, where `cross` is zero anyway.
    first, second = jnp.sinc(angle / jnp.pi), 0.5 * jnp.sinc(angle / (2 * jnp.pi)) ** 2
    return jnp.eye(3, dtype=jnp.float32) + first * cross + second * jnp.matmul(cross, cross, precision=_EXACT)


@dataclasses.dataclass(frozen=True)
class Camera:
    """A fixed MJCF camera: its body, pose in the body frame (position [3], rotation [3, 3]) and vertical
    field of view (degrees). MuJoCo cameras look along their −z axis, with +y up in the image."""

    body: int
    position: np.ndarray
    rotation: np.ndarray
    fovy: float

    @classmethod
    def from_model(cls, model: mujoco.MjModel, name: str) -> "Camera":
        camera = model.camera(name)
        if int(camera.mode[0]) != mujoco.mjtCamLight.mjCAMLIGHT_FIXED:
            raise ValueError(f"camera {name!r} must have mode 'fixed' (on its body) to be cast in JAX")
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, camera.quat)
        return cls(
            body=int(camera.bodyid[0]),
            position=np.asarray(camera.pos, np.float32),
            rotation=rotation.reshape(3, 3).astype(np.float32),
            fovy=float(camera.fovy[0]),
        )

    def world_pose(
        self, xpos: jax.Array, xmat: jax.Array, offset: PoseOffset = NO_OFFSET
    ) -> tuple[jax.Array, jax.Array]:
        """(position [3], rotation [3, 3]) in the world, from the bodies' poses xpos [nbody, 3] and
        xmat [nbody, 3, 3], with the camera moved by `offset` in its own frame."""
        # The offset is composed in the body's frame first: a zero one then adds exact zeros and multiplies by an
        # exact identity, so the pose (and the image) is bit for bit the one without it.
        position = self.position + jnp.matmul(self.rotation, jnp.asarray(offset.shift), precision=_EXACT)
        rotation = jnp.matmul(self.rotation, rotation_of(offset.turn), precision=_EXACT)
        body_rotation = xmat[self.body].reshape(3, 3)
        return (
            xpos[self.body] + jnp.matmul(body_rotation, position, precision=_EXACT),
            jnp.matmul(body_rotation, rotation, precision=_EXACT),
        )


def ray_directions(fovy: float, resolution: int) -> jax.Array:
    """[R, R, 3] unit ray directions in the camera frame, row 0 at the image's top."""
    half_extent = np.tan(np.deg2rad(fovy) / 2)
    ticks = ((np.arange(resolution) + 0.5) / resolution * 2 - 1) * half_extent
    x = np.broadcast_to(ticks[None, :], (resolution, resolution))
    y = np.broadcast_to(-ticks[:, None], (resolution, resolution))
    rays = np.stack([x, y, -np.ones_like(x)], axis=-1)
    return jnp.asarray(rays / np.linalg.norm(rays, axis=-1, keepdims=True), jnp.float32)


def _nearer_of(test: RayTest, camera_rays: Vector, nearest: Hit, geom: tuple) -> tuple[Hit, None]:
    """(The nearer of `nearest` and one geom's hit, None), a `lax.scan` step over the geoms of `test`'s type. `geom`
    is (rotation [3, 3] from the camera's frame into the geom's, the camera's position [3] in the geom's frame,
    size [3], luma); the hit's brightness is the luma lit by its cosine."""
    turn, origin, size, luma = geom
    direction = tuple(
        turn[row, 0] * camera_rays[0] + turn[row, 1] * camera_rays[1] + turn[row, 2] * camera_rays[2]
        for row in range(3)
    )
    distance, cosine = test((origin[0], origin[1], origin[2]), direction, size)
    return _nearer(nearest, (distance, luma * (AMBIENT + (1 - AMBIENT) * cosine))), None


def cast(
    scene: Scene,
    geom_size: jax.Array,
    geom_xpos: jax.Array,
    geom_xmat: jax.Array,
    position: jax.Array,
    rotation: jax.Array,
    rays: jax.Array,
    luma: jax.Array | np.ndarray | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Nearest hit of rays from a camera at `position` [3], turned by `rotation` [3, 3], along unit `rays` [N, 3]
    in the camera's frame: (distance [N], inf on a miss; brightness [N], 0 on a miss). `luma` [G] replaces the
    scene's brightness of its geoms (`Scene.luma`) where given."""
    ids = scene.geoms
    geom_rotations = geom_xmat[ids].reshape(-1, 3, 3)
    # Each geom's frame from the camera's (Rᵀ_geom R_camera) and the camera in each geom's frame, both tiny: the
    # per-ray work of a geom is then element-wise over the rays, and fuses into one loop.
    to_geom = jnp.einsum("gji,jk->gik", geom_rotations, rotation, precision=_EXACT)
    origins = jnp.einsum("gji,gj->gi", geom_rotations, position - geom_xpos[ids], precision=_EXACT)
    geoms = (to_geom, origins, geom_size[ids], scene.luma if luma is None else luma)
    camera_rays = (rays[:, 0], rays[:, 1], rays[:, 2])
    hit = (jnp.full(rays.shape[:1], jnp.inf), jnp.zeros(rays.shape[:1]))
    # One scan per type keeps the program's size independent of the number of geoms: unrolled over every geom,
    # `ppo_peg_pixels` compiled for ~2 min on an H100.
    for geom_type, members in scene.groups:
        nearer = functools.partial(_nearer_of, RAY_TESTS[geom_type], camera_rays)
        hit, _ = jax.lax.scan(nearer, hit, tuple(part[members] for part in geoms))
    return hit


def render(
    scene: Scene,
    camera: Camera,
    resolution: int,
    geom_size: jax.Array,
    geom_xpos: jax.Array,
    geom_xmat: jax.Array,
    xpos: jax.Array,
    xmat: jax.Array,
    offset: PoseOffset = NO_OFFSET,
    luma: jax.Array | np.ndarray | None = None,
) -> tuple[jax.Array, jax.Array]:
    """(depth [R, R] metres along the optical axis, `FAR` where nothing is hit; gray [R, R] in [0, 1]) seen by
    `camera`, moved by `offset` in its own frame, in a scene posed by geom_xpos [ngeom, 3], geom_xmat [ngeom, 3, 3]
    (or [ngeom, 9]), xpos [nbody, 3] and xmat [nbody, 3, 3] (or [nbody, 9]) with sizes geom_size [ngeom, 3], its
    geoms as bright as `luma` [G] where given (else `Scene.luma`)."""
    position, rotation = camera.world_pose(xpos, xmat.reshape(-1, 3, 3), offset)
    local = ray_directions(camera.fovy, resolution).reshape(-1, 3)
    distance, gray = cast(scene, geom_size, geom_xpos, geom_xmat, position, rotation, local, luma)
    depth = jnp.where(jnp.isfinite(distance), distance * -local[:, 2], FAR)
    return depth.reshape(resolution, resolution), gray.reshape(resolution, resolution)
