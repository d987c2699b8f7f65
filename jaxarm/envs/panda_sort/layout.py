"""Where things stand on the table: tables, bins, the spawn region and the optional blocker bar.

One frozen `Layout` is the single source of these numbers: `model.py` builds geoms from it and `reward.py`
scores objects against it, so the two can never disagree. Coordinates are metres in the world frame;
the robot base is at the origin on the near edge of the table, the table top is z = 0.
"""

import dataclasses

SHAPE_CUBE = 0
SHAPE_CYLINDER = 1
SHAPE_SPHERE = 2
SHAPE_NAMES = ("cube", "cylinder", "sphere")
"""Shape ids; bin k (in `Layout.bin_centers` order) is the correct bin of shape k."""


@dataclasses.dataclass(frozen=True)
class BoxGeom:
    """An axis-aligned box: centre (x, y, z) and half-sizes (hx, hy, hz)."""

    center: tuple[float, float, float]
    half: tuple[float, float, float]


@dataclasses.dataclass(frozen=True)
class View:
    """Where a drawing camera stands: its position and its image's right and up axes (MJCF `xyaxes`), in the
    world frame."""

    pos: tuple[float, float, float]
    xyaxes: tuple[float, float, float, float, float, float]


TOSS_VIEW = View(pos=(2.6, 0.45, 1.05), xyaxes=(0.0, 1.0, 0.0, -0.28, 0.0, 0.96))
"""The tosser's video camera: farther back than scene.xml's `front`, so that the frame holds the arm, the gap
and the far table's bins, and the arc of a throw between them."""


@dataclasses.dataclass(frozen=True)
class Layout:
    """Static scene geometry.

    Attributes:
      tables: table top boxes (top faces at z = 0).
      bin_centers: (x, y) of the cube, cylinder and sphere bins, in SHAPE_* order. The bins stand in a row
        along x and share their cross walls.
      bin_half: half-size of a bin's inside (square).
      bin_wall_height: wall height; an object whose centre is inside a bin and below this height is in it.
      bin_wall_half_thickness: half thickness of the walls.
      spawn_low: (x, y) lower corner of the object spawn region.
      spawn_high: (x, y) upper corner of the object spawn region.
      spawn_cells: (nx, ny) grid of spawn cells; each object gets its own cell, so objects never overlap.
      blocker: optional thin bar between the spawn region and the bins.
      front_view: where the `front` camera (videos) stands, if not where assets/scene.xml puts it.
    """

    tables: tuple[BoxGeom, ...]
    bin_centers: tuple[tuple[float, float], ...]
    bin_half: float = 0.07
    bin_wall_height: float = 0.06
    bin_wall_half_thickness: float = 0.005
    spawn_low: tuple[float, float] = (0.30, -0.26)
    spawn_high: tuple[float, float] = (0.72, 0.16)
    spawn_cells: tuple[int, int] = (3, 3)
    blocker: BoxGeom | None = None
    front_view: View | None = None

    @property
    def bin_walls(self) -> tuple[BoxGeom, ...]:
        """Two long walls along the row plus one cross wall before, between and after the bins."""
        xs = [x for x, _ in self.bin_centers]
        y = self.bin_centers[0][1]
        pitch = xs[1] - xs[0]
        t, h = self.bin_wall_half_thickness, self.bin_wall_height / 2
        x_mid, x_half = (xs[0] + xs[-1]) / 2, (xs[-1] - xs[0]) / 2 + self.bin_half + 2 * t
        long_walls = tuple(BoxGeom((x_mid, y + side * (self.bin_half + t), h), (x_half, t, h)) for side in (-1, 1))
        cross_xs = [xs[0] - pitch / 2] + [x + pitch / 2 for x in xs]
        cross_walls = tuple(BoxGeom((x, y, h), (t, self.bin_half, h)) for x in cross_xs)
        return long_walls + cross_walls


def _bin_row(x_first: float, y: float, pitch: float = 0.15) -> tuple[tuple[float, float], ...]:
    return tuple((x_first + k * pitch, y) for k in range(3))


TOSS_BIN_Y = 1.33
"""y of the tosser's bin row: the bins' nearest wall stands 1.25 m from the robot's base, 0.3 m beyond the
tool centre's longest reach at table height (0.92 m, sampled over the joint ranges; tests/envs/
test_panda_sort_tosser.py checks it), so only a throw can score."""


def make_layout(blocker: bool = False, tosser: bool = False) -> Layout:
    """The default scene, optionally with a blocker bar or with the bins out of reach on a second table (a
    tosser: objects must be thrown)."""
    tables: tuple[BoxGeom, ...]
    if tosser:
        # Objects on the near table (y < 0.22); bins on a far table, across a gap of about a metre of floor.
        tables = (
            BoxGeom((0.375, -0.115, -0.02), (0.475, 0.335, 0.02)),
            BoxGeom((0.375, TOSS_BIN_Y, -0.02), (0.475, 0.15, 0.02)),
        )
        bins = _bin_row(0.21, TOSS_BIN_Y)
    else:
        tables = (BoxGeom((0.375, 0.025, -0.02), (0.475, 0.475, 0.02)),)
        bins = _bin_row(0.36, 0.36)
    bar = BoxGeom((0.51, 0.235, 0.05), (0.23, 0.005, 0.05)) if blocker else None
    return Layout(tables=tables, bin_centers=bins, blocker=bar, front_view=TOSS_VIEW if tosser else None)
