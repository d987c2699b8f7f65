"""Depth and grayscale images of a MuJoCo scene, cast analytically in JAX (jit- and vmap-safe, CPU or GPU).

Every geom of our scenes is a primitive (plane, sphere, capsule, cylinder, box), so one ray per pixel is
intersected with each geom in closed form, in the geom's own frame; the nearest hit wins. Depth is the distance
along the camera's optical axis (as a depth camera reports it, not along the ray); grayscale is the geom's
rgba luma under a head light: ambient `AMBIENT` plus Lambert's cos between the surface normal and the ray.
A ray that hits nothing reads depth `FAR` and gray 0. Cameras are the MJCF's <camera>s with mode "fixed" (on
their body: a scene camera on the world, a hand camera on the hand); images are square, `fovy` both ways.

It reads poses (`geom_xpos`, `geom_xmat`, `xpos`, `xmat`) and sizes (`geom_size`, which a task may replace
per episode) as arrays, so it serves mjx.Data and, in tests, MuJoCo's own CPU data alike. It must stay free of
task logic: what an env observes of the images is the env's choice.
"""

import dataclasses
import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

AMBIENT = 0.3
"""Share of a surface's brightness lit regardless of its angle to the ray."""
FAR = 10.0
"""Depth, metres, of a ray that hits nothing."""
_EPSILON = 1e-9


def _safe(x: jax.Array) -> jax.Array:
    """x with exact zeros moved off zero, so that 1/x stays finite (the hit tests then reject the ray)."""
    return jnp.where(jnp.abs(x) < _EPSILON, _EPSILON, x)


def _nearest_positive(*candidates: jax.Array) -> jax.Array:
    """The smallest candidate distance above zero, inf if none."""
    return jnp.min(jnp.stack([jnp.where(t > 0, t, jnp.inf) for t in candidates]), axis=0)


def _ray_sphere(origin, direction, radius, centre_z=0.0) -> jax.Array:
    offset = origin - jnp.array([0.0, 0.0, 1.0]) * centre_z
    b = jnp.dot(offset, direction)
    disc = b * b - (jnp.dot(offset, offset) - radius * radius)
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    near, far = -b - root, -b + root
    return jnp.where(disc >= 0, _nearest_positive(near, far), jnp.inf)


def _ray_tube(origin, direction, radius, half_length) -> jax.Array:
    """The side of a z-axis cylinder of `radius` between z = ±half_length (no caps)."""
    a = direction[0] ** 2 + direction[1] ** 2
    b = origin[0] * direction[0] + origin[1] * direction[1]
    disc = b * b - a * (origin[0] ** 2 + origin[1] ** 2 - radius * radius)
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    hits = []
    for t in ((-b - root) / _safe(a), (-b + root) / _safe(a)):
        inside = (disc >= 0) & (a > _EPSILON) & (jnp.abs(origin[2] + t * direction[2]) <= half_length)
        hits.append(jnp.where(inside, t, jnp.inf))
    return _nearest_positive(*hits)


def ray_plane(origin, direction, size) -> jax.Array:
    """Distance along a ray (local frame: origin [3], unit direction [3]) to the plane z = 0 within its half
    extents size[0], size[1] (0: unbounded), inf on a miss."""
    t = -origin[2] / _safe(direction[2])
    point = origin + t * direction
    within = [(size[axis] <= 0) | (jnp.abs(point[axis]) <= size[axis]) for axis in (0, 1)]
    return jnp.where(within[0] & within[1] & (t > 0), t, jnp.inf)


def ray_sphere(origin, direction, size) -> jax.Array:
    """As `ray_plane`, for a sphere of radius size[0]."""
    return _ray_sphere(origin, direction, size[0])


def ray_capsule(origin, direction, size) -> jax.Array:
    """As `ray_plane`, for a capsule of radius size[0] whose segment spans z = ±size[1]."""
    radius, half_length = size[0], size[1]
    return _nearest_positive(
        _ray_tube(origin, direction, radius, half_length),
        _ray_sphere(origin, direction, radius, half_length),
        _ray_sphere(origin, direction, radius, -half_length),
    )


def ray_cylinder(origin, direction, size) -> jax.Array:
    """As `ray_plane`, for a cylinder of radius size[0] spanning z = ±size[1]."""
    radius, half_length = size[0], size[1]
    caps = []
    for z in (half_length, -half_length):
        t = (z - origin[2]) / _safe(direction[2])
        point = origin + t * direction
        caps.append(jnp.where(point[0] ** 2 + point[1] ** 2 <= radius * radius, t, jnp.inf))
    return _nearest_positive(_ray_tube(origin, direction, radius, half_length), *caps)


def ray_box(origin, direction, size) -> jax.Array:
    """As `ray_plane`, for a box of half sizes size[:3] (slab test)."""
    inverse = 1.0 / _safe(direction)
    first, second = (-size - origin) * inverse, (size - origin) * inverse
    enter = jnp.max(jnp.minimum(first, second))
    leave = jnp.min(jnp.maximum(first, second))
    return jnp.where(leave >= jnp.maximum(enter, 0.0), _nearest_positive(enter, leave), jnp.inf)


def surface_normal(geom_type: int, point: jax.Array, size: jax.Array) -> jax.Array:
    """Unit outward normal [3] of a geom at a `point` [3] on its surface, both in its local frame."""
    if geom_type == mujoco.mjtGeom.mjGEOM_PLANE:
        return jnp.array([0.0, 0.0, 1.0])
    if geom_type == mujoco.mjtGeom.mjGEOM_BOX:
        axis = jnp.argmax(jnp.abs(point) / size)
        return jnp.sign(point) * jax.nn.one_hot(axis, 3)
    if geom_type == mujoco.mjtGeom.mjGEOM_CYLINDER:
        on_cap = jnp.abs(point[2]) >= size[1] - 1e-6
        side = point * jnp.array([1.0, 1.0, 0.0])
        normal = jnp.where(on_cap, jnp.array([0.0, 0.0, 1.0]) * jnp.sign(point[2]), side)
        return normal / jnp.maximum(jnp.linalg.norm(normal), _EPSILON)
    axis_point = jnp.zeros(3)
    if geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE:
        axis_point = jnp.array([0.0, 0.0, 1.0]) * jnp.clip(point[2], -size[1], size[1])
    normal = point - axis_point
    return normal / jnp.maximum(jnp.linalg.norm(normal), _EPSILON)


RAY_TESTS: dict[int, Callable[[jax.Array, jax.Array, jax.Array], jax.Array]] = {
    mujoco.mjtGeom.mjGEOM_PLANE: ray_plane,
    mujoco.mjtGeom.mjGEOM_SPHERE: ray_sphere,
    mujoco.mjtGeom.mjGEOM_CAPSULE: ray_capsule,
    mujoco.mjtGeom.mjGEOM_CYLINDER: ray_cylinder,
    mujoco.mjtGeom.mjGEOM_BOX: ray_box,
}
"""Geom type -> its ray test (origin [3], unit direction [3], size [3]) -> distance, all in the geom's frame."""


@dataclasses.dataclass(frozen=True)
class Scene:
    """What the caster needs of a compiled model, resolved once outside jit.

    Attributes:
      groups: (geom type, geom ids [K]) per primitive type present: each group is tested in one vmap.
      luma: [ngeom] brightness of each geom's rgba (Rec. 601 weights).
    """

    groups: tuple[tuple[int, np.ndarray], ...]
    luma: np.ndarray

    @classmethod
    def from_model(cls, model: mujoco.MjModel) -> "Scene":
        """Every visible geom (alpha > 0) of `model`; ValueError naming a geom that is not a primitive."""
        visible = np.flatnonzero(model.geom_rgba[:, 3] > 0)
        for geom in visible:
            if int(model.geom_type[geom]) not in RAY_TESTS:
                kind = mujoco.mjtGeom(int(model.geom_type[geom])).name
                raise ValueError(f"geom {model.geom(geom).name or geom} is a {kind}: the camera casts primitives only")
        groups = tuple(
            (geom_type, visible[model.geom_type[visible] == geom_type])
            for geom_type in RAY_TESTS
            if np.any(model.geom_type[visible] == geom_type)
        )
        luma = model.geom_rgba[:, :3] @ np.array([0.299, 0.587, 0.114])
        return cls(groups=groups, luma=luma.astype(np.float32))


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

    def world_pose(self, xpos: jax.Array, xmat: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(position [3], rotation [3, 3]) in the world, from the bodies' poses xpos [nbody, 3] and
        xmat [nbody, 3, 3]."""
        body_rotation = xmat[self.body].reshape(3, 3)
        return xpos[self.body] + body_rotation @ self.position, body_rotation @ self.rotation


def ray_directions(fovy: float, resolution: int) -> jax.Array:
    """[R, R, 3] unit ray directions in the camera frame, row 0 at the image's top."""
    half_extent = np.tan(np.deg2rad(fovy) / 2)
    ticks = ((np.arange(resolution) + 0.5) / resolution * 2 - 1) * half_extent
    x = np.broadcast_to(ticks[None, :], (resolution, resolution))
    y = np.broadcast_to(-ticks[:, None], (resolution, resolution))
    rays = np.stack([x, y, -np.ones_like(x)], axis=-1)
    return jnp.asarray(rays / np.linalg.norm(rays, axis=-1, keepdims=True), jnp.float32)


def cast(
    scene: Scene,
    geom_size: jax.Array,
    geom_xpos: jax.Array,
    geom_xmat: jax.Array,
    origin: jax.Array,
    directions: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """Nearest hit of rays from `origin` [3] along unit world `directions` [N, 3]: (distance [N], inf on a
    miss; brightness [N], 0 on a miss)."""
    nearest = jnp.full(directions.shape[:1], jnp.inf)
    brightness = jnp.zeros(directions.shape[:1])
    for geom_type, ids in scene.groups:
        rotations = geom_xmat[ids].reshape(-1, 3, 3)
        local_origins = jnp.einsum("kji,kj->ki", rotations, origin - geom_xpos[ids])  # Rᵀ (origin − centre)
        local_directions = jnp.einsum("kji,nj->kni", rotations, directions)
        sizes = geom_size[ids]
        per_ray = jax.vmap(RAY_TESTS[geom_type], in_axes=(None, 0, None))
        distances = jax.vmap(per_ray)(local_origins, local_directions, sizes)  # [K, N]
        closest = jnp.argmin(distances, axis=0)
        distance = jnp.min(distances, axis=0)
        hit_origin, hit_direction = (
            local_origins[closest],
            jnp.take_along_axis(local_directions, closest[None, :, None], axis=0)[0],
        )
        points = hit_origin + jnp.where(jnp.isfinite(distance), distance, 0.0)[:, None] * hit_direction
        normals = jax.vmap(functools.partial(surface_normal, geom_type))(points, sizes[closest])
        cosine = jnp.abs(jnp.sum(normals * hit_direction, axis=-1))
        shade = jnp.asarray(scene.luma)[ids][closest] * (AMBIENT + (1 - AMBIENT) * cosine)
        closer = distance < nearest
        nearest = jnp.where(closer, distance, nearest)
        brightness = jnp.where(closer, shade, brightness)
    return nearest, brightness


def render(
    scene: Scene,
    camera: Camera,
    resolution: int,
    geom_size: jax.Array,
    geom_xpos: jax.Array,
    geom_xmat: jax.Array,
    xpos: jax.Array,
    xmat: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """(depth [R, R] metres along the optical axis, `FAR` where nothing is hit; gray [R, R] in [0, 1]) seen by
    `camera` in a scene posed by geom_xpos [ngeom, 3], geom_xmat [ngeom, 3, 3] (or [ngeom, 9]), xpos [nbody, 3]
    and xmat [nbody, 3, 3] (or [nbody, 9]) with sizes geom_size [ngeom, 3]."""
    position, rotation = camera.world_pose(xpos, xmat.reshape(-1, 3, 3))
    local = ray_directions(camera.fovy, resolution).reshape(-1, 3)
    distance, gray = cast(scene, geom_size, geom_xpos, geom_xmat, position, local @ rotation.T)
    depth = jnp.where(jnp.isfinite(distance), distance * -local[:, 2], FAR)
    return depth.reshape(resolution, resolution), gray.reshape(resolution, resolution)
