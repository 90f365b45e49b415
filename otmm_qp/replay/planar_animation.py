r"""Animated GIF of planar-arm runs: one panel per controller, side by side.

Each panel shows, at the stored joint coordinates of each frame, the links (coloured by
σ_min, blue → red as σ_min falls from σ_S to 10⁻⁴), the end-effector tip (a magenta dot
drawn from the links' forward kinematics), the desired path (dashed), the path travelled so
far and the manipulability ellipse at the tip,

.. math:: \mathcal{E} = \{ J\dot q : \|\dot q\| \le 1 \} = \{ U\Sigma u : \|u\| \le 1 \},

drawn to scale ``ellipse_scale`` [m per unit singular value]. The stored σ_min is printed.

Frames are evenly spaced stored steps; when the GIF exceeds ``max_bytes`` the frame count is
halved until it fits (the output line says so). A JSON sidecar gives, per frame, the step
shown and, per panel, the data → pixel map (used by the tests to locate the drawn tip).
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.paper import SIGMA_S
from otmm_qp.paths import atomic_write_bytes
from otmm_qp.replay.frames import FramePlan, plan_frames
from otmm_qp.replay.stored_runs import StoredRun
from otmm_qp.robots.robot import FloatArray, Robot

DEFAULT_MAX_FRAMES = 80
DEFAULT_MAX_BYTES = 2_500_000
DEFAULT_SIGMA_S = SIGMA_S
TIP_COLOR = (255, 0, 255)
_PANEL_INCHES = 2.4
#: Angles of the manipulability ellipse's outline [rad].
_ELLIPSE_ANGLES = np.linspace(0.0, 2.0 * np.pi, 48)
_DPI = 80


@dataclass
class AnimationResult:
    """What :func:`write_planar_animation` wrote.

    Attributes:
        path: The GIF.
        sidecar: Its JSON description (frames, steps, pixel maps).
        plan: Frames shown.
        shrunk: Whether frames were dropped to respect ``max_bytes``.
    """

    path: Path
    sidecar: Path
    plan: FramePlan
    shrunk: bool


def _joints(lengths: FloatArray, q: FloatArray) -> FloatArray:
    """Joint and tip positions [m], shape ``(m + 1, 2)``: base at the origin."""
    theta = np.cumsum(q)
    steps = lengths[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
    return np.vstack([np.zeros(2), np.cumsum(steps, axis=0)])


def _palette_image() -> Any:
    """A fixed 216-colour ('web-safe') palette: exact tip colour, compact frames."""
    from PIL import Image

    levels = (0, 51, 102, 153, 204, 255)
    colours = [c for r in levels for g in levels for b in levels for c in (r, g, b)]
    palette = Image.new("P", (1, 1))
    palette.putpalette(colours + [0] * (768 - len(colours)))
    return palette


def _sigma_colour(sigma: float, sigma_s: float) -> tuple[float, float, float]:
    high, low = np.log10(sigma_s), -4.0
    level = 1.0 if not np.isfinite(sigma) or sigma <= 0 else (high - np.log10(sigma)) / (high - low)
    level = float(np.clip(level, 0.0, 1.0))
    return (0.15 + 0.75 * level, 0.3 * (1 - level), 0.75 * (1 - level) + 0.1 * level)


@dataclass
class _Panel:
    """One controller's axes, its run and the artists redrawn on every frame."""

    axes: Any
    run: StoredRun
    trace: Any
    ellipse: Any
    links: Any
    target: Any
    tip: Any
    text: Any

    def artists(self) -> tuple[Any, ...]:
        """The moving artists, in drawing order."""
        return (self.trace, self.ellipse, self.links, self.target, self.tip, self.text)


def _render(
    robot: Robot,
    title: str,
    runs: Sequence[StoredRun],
    plan: FramePlan,
    sigma_s: float,
) -> tuple[bytes, list[dict[str, Any]], tuple[int, int]]:
    """Draw the frames of ``plan`` as a GIF: ``(bytes, per-panel pixel maps, size [px])``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    arm: Any = robot
    lengths = np.asarray(arm.link_lengths, dtype=np.float64)
    reach = float(lengths.sum()) * 1.08
    count = len(runs)
    columns = min(count, 4)
    rows = int(np.ceil(count / columns))
    figure = plt.figure(figsize=(_PANEL_INCHES * columns, _PANEL_INCHES * rows + 0.35), dpi=_DPI)
    figure.suptitle(title, fontsize=9)
    ellipse_scale = 0.3 * reach / _largest_sigma(robot, runs, plan)
    panels = [
        _add_panel(figure.add_subplot(rows, columns, i + 1), run, reach)
        for i, run in enumerate(runs)
    ]
    figure.tight_layout(rect=(0, 0, 1, 0.97))
    canvas: Any = figure.canvas
    canvas.draw()
    # Blitting: the axes, ticks and desired paths are drawn once; per frame only the moving
    # artists are drawn over a copy of that background (text layout dominates a full draw).
    background = canvas.copy_from_bbox(figure.bbox)
    width, height = figure.canvas.get_width_height()
    maps = [_pixel_map(panel.axes, height) for panel in panels]
    palette = _palette_image()
    images = []
    for k in plan.indices:
        canvas.restore_region(background)
        for panel in panels:
            _draw_panel(panel, int(k), robot, lengths, ellipse_scale, sigma_s)
        rgba = np.asarray(canvas.buffer_rgba())
        frame = Image.fromarray(rgba[:, :, :3].copy())
        images.append(frame.quantize(palette=palette, dither=Image.Dither.NONE))
    plt.close(figure)
    return _encode_gif(images, runs[0], plan), maps, (width, height)


def _largest_sigma(robot: Robot, runs: Sequence[StoredRun], plan: FramePlan) -> float:
    """Largest singular value of ``J`` over the finite frames shown (at least 1e-9)."""
    sigma_max = 1e-9
    for run in runs:
        for q in run.q[np.minimum(plan.indices, run.steps - 1)]:
            if np.all(np.isfinite(q)):
                sigma_max = max(
                    sigma_max, float(np.linalg.svd(robot.jacobian(q), compute_uv=False)[0])
                )
    return sigma_max


def _add_panel(axes: Any, run: StoredRun, reach: float) -> _Panel:
    """Set up one controller's axes (limits, title, desired path) and its moving artists."""
    axes.set_xlim(-reach, reach)
    axes.set_ylim(-reach, reach)
    axes.set_aspect("equal")
    axes.tick_params(labelsize=6, length=2)
    axes.set_title(run.controller, fontsize=8)
    desired = run.position_desired
    axes.plot(desired[:, 0], desired[:, 1], "--", color="0.55", lw=0.9)
    trace = axes.plot([], [], "-", color="#1f77b4", lw=0.9)[0]
    ellipse = axes.plot([], [], "-", color="#2ca02c", lw=0.9)[0]
    links = axes.plot([], [], "-o", lw=2.4, ms=3.0, color="0.3")[0]
    target = axes.plot([], [], "x", color="0.25", ms=5)[0]
    tip = axes.plot([], [], "o", ms=4.5, color=np.array(TIP_COLOR) / 255, antialiased=False)[0]
    text = axes.text(0.03, 0.03, "", transform=axes.transAxes, fontsize=6.5)
    panel = _Panel(axes, run, trace, ellipse, links, target, tip, text)
    for artist in panel.artists():
        artist.set_animated(True)
    return panel


def _pixel_map(axes: Any, height: int) -> dict[str, float]:
    """Data → image pixel map of ``axes``: pixel = (sx·x + ox, sy·y + oy), y downwards."""
    origin = axes.transData.transform((0.0, 0.0))
    unit = axes.transData.transform((1.0, 1.0)) - origin
    return {
        "sx": float(unit[0]),
        "ox": float(origin[0]),
        "sy": float(-unit[1]),
        "oy": float(height - origin[1]),
    }


def _draw_panel(
    panel: _Panel,
    k: int,
    robot: Robot,
    lengths: FloatArray,
    ellipse_scale: float,
    sigma_s: float,
) -> None:
    """Draw step ``k`` of a panel's run (arm, tip, target, trace, ellipse, text); skip NaN q."""
    run = panel.run
    row = min(k, run.steps - 1)
    q = run.q[row]
    if not np.all(np.isfinite(q)):
        return
    points = _joints(lengths, q)
    panel.links.set_data(points[:, 0], points[:, 1])
    panel.links.set_color(_sigma_colour(float(run.sigma_min[row]), sigma_s))
    panel.tip.set_data([points[-1, 0]], [points[-1, 1]])
    panel.target.set_data([run.position_desired[row, 0]], [run.position_desired[row, 1]])
    panel.trace.set_data(run.position[: row + 1, 0], run.position[: row + 1, 1])
    u, s, _ = np.linalg.svd(robot.jacobian(q))
    outline = points[-1][:, None] + ellipse_scale * (u @ np.diag(s)) @ np.vstack(
        [np.cos(_ELLIPSE_ANGLES), np.sin(_ELLIPSE_ANGLES)]
    )
    panel.ellipse.set_data(outline[0], outline[1])
    panel.text.set_text(f"t = {run.t[row]:.2f} s   σmin = {run.sigma_min[row]:.2e}")
    for artist in panel.artists():
        panel.axes.draw_artist(artist)


def _encode_gif(images: list[Any], reference: StoredRun, plan: FramePlan) -> bytes:
    """The frames as a looping GIF, timed like ``reference`` (at least 20 ms per frame)."""
    if plan.frames > 1:
        span = float(reference.t[min(int(plan.indices[-1]), reference.steps - 1)] - reference.t[0])
        duration = max(20, int(round(1000.0 * span / (plan.frames - 1))))
    else:
        duration = 500
    buffer = io.BytesIO()
    images[0].save(
        buffer,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=duration,
        loop=0,
        optimize=False,
    )
    return buffer.getvalue()


def write_planar_animation(
    path: Path,
    title: str,
    robot: Robot,
    runs: Sequence[StoredRun],
    max_frames: int = DEFAULT_MAX_FRAMES,
    max_bytes: int = DEFAULT_MAX_BYTES,
    sigma_s: float = DEFAULT_SIGMA_S,
) -> AnimationResult:
    """Write the GIF of one scenario's planar runs and its JSON sidecar (atomically).

    Args:
        path: Output ``.gif``.
        title: Figure title.
        robot: The runs' :class:`~otmm_qp.robots.planar_arm.PlanarArm`.
        runs: One stored run per controller, non-empty.
        max_frames: Upper bound on frames [-].
        max_bytes: Upper bound on the GIF size [bytes]; frames are halved until it fits.
        sigma_s: σ_S of the colour scale [-].
    """
    steps = max(r.steps for r in runs)
    plan = plan_frames(steps, max_frames)
    shrunk = False
    while True:
        data, maps, size = _render(robot, title, runs, plan, sigma_s)
        if len(data) <= max_bytes or plan.frames <= 2:
            break
        plan = plan_frames(steps, plan.frames // 2)
        shrunk = True
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, data)
    sidecar = path.with_suffix(".json")
    description = {
        "title": title,
        "kind": "planar-gif",
        "file": path.name,
        "frames": plan.frames,
        "steps": plan.indices.tolist(),
        "stored_steps": plan.steps,
        "size": list(size),
        "controllers": [r.controller for r in runs],
        "pixel_maps": maps,
    }
    sidecar.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(sidecar, (json.dumps(description, indent=1) + "\n").encode("utf-8"))
    return AnimationResult(path, sidecar, plan, shrunk)
