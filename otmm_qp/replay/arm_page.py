r"""Self-contained offline HTML replay of URDF-arm runs (MeshCat viewer, inlined).

One page per scenario (experiment × loop mode): the robot's meshes moved through the stored
joint coordinates, the desired (green) and actual (per controller) end-effector paths as
lines, a controller selector, play/pause, a time slider and a σ_min gauge with the σ_min(t)
curve. The arm glows red as σ_min falls below σ_S:

.. math:: \text{glow} = \operatorname{clip}\!\Big(\frac{\log_{10}\sigma_S - \log_{10}\sigma_{min}}
          {\log_{10}\sigma_S - \log_{10}\sigma_{floor}}, 0, 1\Big),\quad \sigma_{floor} = 10^{-4}

The URL hash ``#frame=K&controller=I`` sets the slider and the controller (used by the
browser tests and for sharing a moment of a run).
"""

from __future__ import annotations

import base64
import gzip
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from otmm_qp.output.escape import escape, fill_template
from otmm_qp.paper import SIGMA_S
from otmm_qp.paths import atomic_write_bytes
from otmm_qp.replay.arm_scene import build_arm_scene, geometry_transforms
from otmm_qp.replay.frames import FramePlan, plan_frames
from otmm_qp.replay.stored_runs import StoredRun
from otmm_qp.robots.robot import Robot

#: Bytes of per-frame transform data allowed before frames are decimated.
DEFAULT_MAX_FRAME_BYTES = 3_000_000
#: σ_S used for the arm colour [-] (the metrics default).
DEFAULT_SIGMA_S = SIGMA_S
PATH_COLORS = (
    0x1F77B4,
    0xFF7F0E,
    0x9467BD,
    0x8C564B,
    0xE377C2,
    0x17BECF,
    0xBCBD22,
    0x7F7F7F,
    0xD62728,
)


@dataclass
class PageResult:
    """What :func:`write_arm_page` wrote.

    Attributes:
        path: The HTML file.
        plan: Frames shown.
        warnings: Messages for the user (meshes missing, ...).
    """

    path: Path
    plan: FramePlan
    warnings: list[str]


def _viewer_bundle() -> str:
    from otmm_qp.replay.arm_scene import import_meshcat

    meshcat = import_meshcat()
    bundle = Path(os.path.dirname(meshcat.__file__)) / "viewer" / "dist" / "main.min.js"
    text = bundle.read_text(encoding="utf-8")
    return text.replace("</script", "<\\/script").replace("<!--", "<\\!--")


def _pack(chunks: Sequence[bytes]) -> str:
    """Length-prefixed (uint32 little-endian) chunks, gzipped, base64."""
    raw = b"".join(len(c).to_bytes(4, "little") + c for c in chunks)
    return base64.b64encode(gzip.compress(raw, compresslevel=6, mtime=0)).decode("ascii")


def _finite_list(values: np.ndarray, digits: int = 6) -> list[float | None]:
    return [float(f"{v:.{digits}g}") if np.isfinite(v) else None for v in values]


def write_arm_page(
    path: Path,
    title: str,
    robot: Robot,
    runs: Sequence[StoredRun],
    max_frame_bytes: int = DEFAULT_MAX_FRAME_BYTES,
    sigma_s: float = DEFAULT_SIGMA_S,
) -> PageResult:
    """Write the replay page of one scenario's runs (same robot, same task).

    Args:
        path: Output HTML file (written atomically).
        title: Page title.
        robot: The runs' arm (a PinocchioArm).
        runs: One stored run per controller, non-empty.
        max_frame_bytes: Budget for the per-frame transforms; more steps are decimated.
        sigma_s: σ_S of the colour scale [-].
    """
    desired = runs[0].position_desired
    scene, visualizer, _ = build_arm_scene(
        robot,
        desired,
        [r.position for r in runs],
        [PATH_COLORS[i % len(PATH_COLORS)] for i in range(len(runs))],
    )
    steps = max(r.steps for r in runs)
    per_frame = max(1, len(runs) * len(scene.geometry_paths) * 12 * 4)
    plan = plan_frames(steps, max(2, max_frame_bytes // per_frame))
    transforms = [
        geometry_transforms(visualizer, robot, run.q[np.minimum(plan.indices, run.steps - 1)])
        for run in runs
    ]
    reference = runs[0]
    times = [float(f"{reference.t[min(k, reference.steps - 1)]:.6g}") for k in plan.indices]
    centre, extent = _view(desired, runs)
    meta = {
        "title": title,
        "times": times,
        "steps": plan.indices.tolist(),
        "controllers": [_controller_meta(i, run, plan) for i, run in enumerate(runs)],
        "geometries": scene.geometry_paths,
        "sigmaS": sigma_s,
        "target": [float(v) for v in centre],
        "distance": 1.05 * extent + 0.25,
        "warnings": scene.warnings,
        "note": plan.describe(),
    }
    frames_blob = _pack([np.ascontiguousarray(np.stack(transforms)).tobytes()])
    page = _fill_template(title, meta, scene.commands, frames_blob)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, page.encode("utf-8"))
    return PageResult(path, plan, list(scene.warnings))


def _controller_meta(index: int, run: StoredRun, plan: FramePlan) -> dict[str, Any]:
    """One controller's entry in the page data: name, colour and its values at the frames."""
    rows = np.minimum(plan.indices, run.steps - 1)
    return {
        "name": run.controller,
        "color": f"#{PATH_COLORS[index % len(PATH_COLORS)]:06x}",
        "sigma": _finite_list(run.sigma_min[rows]),
        "actual": [_finite_list(run.position[k], 5) for k in rows],
        "desired": [_finite_list(run.position_desired[k], 5) for k in rows],
        "steps": run.steps,
        "status": [run.status[k] for k in rows],
    }


def _view(desired: np.ndarray, runs: Sequence[StoredRun]) -> tuple[np.ndarray, float]:
    """Centre [m] and largest extent [m] of the finite paths and the base (the origin)."""
    points = np.vstack([desired] + [r.position for r in runs])
    points = np.vstack([points[np.all(np.isfinite(points), axis=1)], np.zeros((1, 3))])
    centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
    extent = float(np.max(points.max(axis=0) - points.min(axis=0)))
    return centre, extent


def _fill_template(
    title: str, meta: dict[str, Any], scene_commands: Sequence[bytes], frames_blob: str
) -> str:
    """The page: ``arm_page.html`` with the title, viewer bundle, data, scene and frames inlined."""
    template = (Path(__file__).parent / "arm_page.html").read_text(encoding="utf-8")
    return fill_template(
        template,
        {
            "TITLE": escape(title, "text"),
            "BUNDLE": _viewer_bundle(),
            "META": escape(meta, "script"),
            "SCENE": _pack(scene_commands),
            "FRAMES": frames_blob,
        },
    )
