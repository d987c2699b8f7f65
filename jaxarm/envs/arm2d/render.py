"""Draws an arm2d state as an RGB image with PIL (no window, no display needed)."""

import numpy as np
from PIL import Image, ImageDraw

from jaxarm.envs.arm2d.arm import Arm2dParams, Arm2dSim, link_end_positions


def draw_frame(sim: Arm2dSim, params: Arm2dParams, size: int = 256) -> np.ndarray:
    """One (non-batched) state -> uint8 [size, size, 3]: goal square (green when the finger is on it), links."""
    scale = size / float(params.world_size)

    def to_pixels(point):
        # World y points up; image rows point down.
        return float(point[0]) * scale, size - float(point[1]) * scale

    image = Image.new("RGB", (size, size), (255, 255, 255))
    draw = ImageDraw.Draw(image)
    half = float(params.goal_size) / 2
    goal = np.asarray(sim.goal)
    left, top = to_pixels(goal + np.array([-half, half]))
    right, bottom = to_pixels(goal + np.array([half, -half]))
    on_goal = int(sim.hold_count) > 0
    draw.rectangle([left, top, right, bottom], fill=(120, 200, 120) if on_goal else (130, 150, 230))
    points = [to_pixels(params.base_pos)] + [to_pixels(p) for p in np.asarray(link_end_positions(sim.angles, params))]
    draw.line(points, fill=(60, 60, 60), width=max(2, size // 64))
    for x, y in points:
        radius = max(2, size // 96)
        draw.ellipse([x - radius, y - radius, x + radius, y + radius], fill=(200, 80, 60))
    return np.asarray(image)
