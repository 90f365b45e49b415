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
import html
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.replay.arm_scene import build_arm_scene, geometry_transforms
from otmm_qp.replay.frames import FramePlan, plan_frames
from otmm_qp.replay.stored_runs import StoredRun
from otmm_qp.robots.robot import Robot

#: Bytes of per-frame transform data allowed before frames are decimated.
DEFAULT_MAX_FRAME_BYTES = 3_000_000
#: σ_S used for the arm colour [-] (the metrics default).
DEFAULT_SIGMA_S = 0.05
PATH_COLORS = (0x1F77B4, 0xFF7F0E, 0x9467BD, 0x8C564B, 0xE377C2, 0x17BECF, 0xBCBD22, 0x7F7F7F, 0xD62728)


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
    return text.replace("</script", "<\\/script")


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
    transforms = []
    controllers = []
    for i, run in enumerate(runs):
        rows = np.minimum(plan.indices, run.steps - 1)
        transforms.append(
            geometry_transforms(visualizer, robot, run.q[rows])
        )
        controllers.append(
            {
                "name": run.controller,
                "color": f"#{PATH_COLORS[i % len(PATH_COLORS)]:06x}",
                "sigma": _finite_list(run.sigma_min[rows]),
                "actual": [_finite_list(run.position[k], 5) for k in rows],
                "desired": [_finite_list(run.position_desired[k], 5) for k in rows],
                "steps": run.steps,
                "status": [run.status[k] for k in rows],
            }
        )
    reference = runs[0]
    times = [float(f"{reference.t[min(k, reference.steps - 1)]:.6g}") for k in plan.indices]
    points = np.vstack([desired] + [r.position for r in runs])
    points = np.vstack([points[np.all(np.isfinite(points), axis=1)], np.zeros((1, 3))])
    centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
    extent = float(np.max(points.max(axis=0) - points.min(axis=0)))
    meta = {
        "title": title,
        "times": times,
        "steps": plan.indices.tolist(),
        "controllers": controllers,
        "geometries": scene.geometry_paths,
        "sigmaS": sigma_s,
        "target": [float(v) for v in centre],
        "distance": 1.05 * extent + 0.25,
        "warnings": scene.warnings,
        "note": plan.describe(),
    }
    frames_blob = _pack([np.ascontiguousarray(np.stack(transforms)).tobytes()])
    page = (
        _TEMPLATE.replace("__TITLE__", html.escape(title))
        .replace("__BUNDLE__", _viewer_bundle())
        .replace("__META__", json.dumps(meta, separators=(",", ":")).replace("</", "<\\/"))
        .replace("__SCENE__", _pack(scene.commands))
        .replace("__FRAMES__", frames_blob)
    )
    _atomic_write(path, page.encode("utf-8"))
    return PageResult(path, plan, list(scene.warnings))


def _atomic_write(path: Path, data: bytes) -> None:
    try:
        from otmm_qp.output.paths import atomic_write_bytes
    except ImportError:  # until branch hostile-input is merged
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f".{path.name}.tmp")
        temporary.write_bytes(data)
        os.replace(temporary, path)
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, data)


_TEMPLATE = r"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<meta name="viewport" content="width=device-width,initial-scale=1">
<style>
html,body{margin:0;height:100%;overflow:hidden;font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif}
#meshcat-pane{position:absolute;inset:0}
#panel{position:absolute;left:0;right:0;bottom:0;height:118px;background:rgba(244,246,250,.92);border-top:1px solid #cdd3dc;
padding:6px 12px;box-sizing:border-box;font-size:13px;color:#1d2430}
#row1,#row2{display:flex;align-items:center;gap:10px}
#time{flex:1}#play{width:70px}#tlabel{width:120px;font-variant-numeric:tabular-nums}
#gauge{position:relative;width:220px;height:14px;background:linear-gradient(90deg,#c62828,#ff9800 40%,#e0e0e0 60%,#e0e0e0);border:1px solid #999}
#gmark{position:absolute;top:-3px;width:3px;height:20px;background:#111}
#sigtxt{width:170px;font-variant-numeric:tabular-nums}
#plot{width:100%;height:48px;display:block;margin-top:4px}
#title{position:absolute;left:10px;top:8px;background:rgba(255,255,255,.85);padding:4px 8px;border-radius:4px;font-size:14px}
#warn{color:#a4262c}
#legend span{display:inline-block;margin-right:10px}
</style></head><body>
<div id="meshcat-pane"></div>
<div id="title"><b>__TITLE__</b> <span id="note"></span><div id="legend"></div><div id="warn"></div></div>
<div id="panel">
 <div id="row1"><button id="play" type="button">Play</button>
  <label>controller <select id="controller"></select></label>
  <input id="time" type="range" min="0" max="0" step="1" value="0">
  <span id="tlabel"></span></div>
 <div id="row2"><span>σ<sub>min</sub></span><div id="gauge" title="log scale 1e-5 … 1; σ_S marked"><div id="gmark"></div></div>
  <span id="sigtxt"></span><span id="status"></span></div>
 <canvas id="plot"></canvas>
</div>
<script>__BUNDLE__</script>
<script>
"use strict";
const META = __META__;
const SCENE_B64 = "__SCENE__";
const FRAMES_B64 = "__FRAMES__";
const viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
const THREE = MeshCat.THREE;
const F = META.times.length, C = META.controllers.length, G = META.geometries.length;
let frames = null, current = 0, controller = 0, playing = false, lastTick = 0, materials = [];
window.replayReady = false;

async function unpack(b64) {
  const bytes = Uint8Array.from(atob(b64), c => c.charCodeAt(0));
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
  const buffer = new Uint8Array(await new Response(stream).arrayBuffer());
  const chunks = []; let o = 0;
  while (o < buffer.length) {
    const n = buffer[o] | (buffer[o+1] << 8) | (buffer[o+2] << 16) | (buffer[o+3] << 24); o += 4;
    chunks.push(buffer.slice(o, o + n)); o += n;
  }
  return chunks;
}
function node(path) { return viewer.scene_tree.find(path.split("/").filter(s => s.length)); }
function zup(v) { return new THREE.Vector3(v[0], v[2], -v[1]); }  // MeshCat's camera frame is y-up
function glow(s) {
  if (s === null || !isFinite(s)) return 1;
  const hi = Math.log10(META.sigmaS), lo = -4;
  return Math.min(1, Math.max(0, (hi - Math.log10(Math.max(s, 1e-12))) / (hi - lo)));
}
function collectMaterials() {
  materials = [];
  node("/meshcat/robot/visuals").object.traverse(o => {
    if (!o.material) return;
    const own = m => (m && typeof m.clone === "function") ? m.clone() : m;
    o.material = Array.isArray(o.material) ? o.material.map(own) : own(o.material);
    (Array.isArray(o.material) ? o.material : [o.material]).forEach(m => { if (m && m.emissive) materials.push(m); });
  });
}
function show(k) {
  current = Math.max(0, Math.min(F - 1, k|0));
  const base = (controller * F + current) * G * 12, m = new Float32Array(16);
  for (let g = 0; g < G; g++) {
    const a = frames.subarray(base + g * 12, base + g * 12 + 12);
    m.set([a[0],a[1],a[2],0, a[3],a[4],a[5],0, a[6],a[7],a[8],0, a[9],a[10],a[11],1]);
    node(META.geometries[g]).set_transform(m);
  }
  const c = META.controllers[controller];
  const p = c.actual[current], d = c.desired[current];
  if (p[0] !== null) node("/meshcat/markers/actual").set_transform(new THREE.Matrix4().makeTranslation(p[0], p[1], p[2]).toArray());
  if (d[0] !== null) node("/meshcat/markers/desired").set_transform(new THREE.Matrix4().makeTranslation(d[0], d[1], d[2]).toArray());
  const s = c.sigma[current], h = glow(s);
  materials.forEach(mt => mt.emissive.setRGB(0.85 * h, 0.05 * h, 0.05 * h));
  const x = s === null ? 0 : Math.min(1, Math.max(0, (Math.log10(Math.max(s, 1e-12)) + 5) / 5));
  document.getElementById("gmark").style.left = (x * 217) + "px";
  document.getElementById("sigtxt").textContent = "σmin = " + (s === null ? "n/a" : s.toExponential(2)) + "  (σS = " + META.sigmaS + ")";
  document.getElementById("status").textContent = c.status[current] ? "backend: " + c.status[current] : "";
  document.getElementById("time").value = current;
  document.getElementById("tlabel").textContent = "t = " + META.times[current].toFixed(2) + " s  (" + (current + 1) + "/" + F + ")";
  drawPlot();
  viewer.set_dirty();
}
function selectController(i) {
  controller = Math.max(0, Math.min(C - 1, i|0));
  document.getElementById("controller").value = String(controller);
  for (let j = 0; j < C; j++) node("/meshcat/paths/actual_" + j).object.visible = (j === controller);
  show(current);
}
function drawPlot() {
  const cv = document.getElementById("plot"), w = cv.clientWidth, h = cv.clientHeight;
  if (cv.width !== w) { cv.width = w; cv.height = h; }
  const ctx = cv.getContext("2d"); ctx.clearRect(0, 0, w, h);
  const y = s => h - 2 - (h - 4) * Math.min(1, Math.max(0, (Math.log10(Math.max(s, 1e-12)) + 5) / 5));
  ctx.strokeStyle = "#888"; ctx.setLineDash([4, 3]); ctx.beginPath();
  ctx.moveTo(0, y(META.sigmaS)); ctx.lineTo(w, y(META.sigmaS)); ctx.stroke(); ctx.setLineDash([]);
  META.controllers.forEach((c, j) => {
    ctx.strokeStyle = c.color; ctx.lineWidth = j === controller ? 2.2 : 0.8; ctx.globalAlpha = j === controller ? 1 : 0.35;
    ctx.beginPath(); let started = false;
    c.sigma.forEach((s, k) => { if (s === null) { started = false; return; }
      const px = F > 1 ? k * (w - 1) / (F - 1) : 0; if (started) ctx.lineTo(px, y(s)); else { ctx.moveTo(px, y(s)); started = true; } });
    ctx.stroke();
  });
  ctx.globalAlpha = 1; ctx.strokeStyle = "#111"; ctx.lineWidth = 1;
  const cx = F > 1 ? current * (w - 1) / (F - 1) : 0; ctx.beginPath(); ctx.moveTo(cx, 0); ctx.lineTo(cx, h); ctx.stroke();
  ctx.fillStyle = "#444"; ctx.font = "10px sans-serif"; ctx.fillText("σmin(t), log 1e-5…1; dashed: σS", 4, 10);
}
function readHash() {
  const q = new URLSearchParams(location.hash.slice(1));
  if (q.has("controller")) {
    const v = q.get("controller"), byName = META.controllers.findIndex(c => c.name === v);
    selectController(byName >= 0 ? byName : parseInt(v, 10) || 0);
  }
  if (q.has("frame")) show(parseInt(q.get("frame"), 10) || 0);
  else if (q.has("t")) { const t = parseFloat(q.get("t")); let k = 0; while (k < F - 1 && META.times[k + 1] <= t) k++; show(k); }
}
function tick(now) {
  if (playing) {
    if (now - lastTick > 1000 * (META.times.length > 1 ? (META.times[1] - META.times[0]) : 0.02)) {
      lastTick = now; if (current >= F - 1) show(0); else show(current + 1);
    }
    requestAnimationFrame(tick);
  }
}
async function main() {
  for (const chunk of await unpack(SCENE_B64)) viewer.handle_command_bytearray(chunk);
  const raw = (await unpack(FRAMES_B64))[0];
  frames = new Float32Array(raw.buffer, raw.byteOffset, raw.byteLength / 4);
  collectMaterials();
  const target = zup(META.target);
  const eye = new THREE.Vector3(0.55, 0.62, 0.7).normalize().multiplyScalar(META.distance).add(target);
  viewer.set_property(["Cameras", "default", "rotated", "<object>"], "position", [eye.x, eye.y, eye.z]);
  viewer.controls.target.copy(target); viewer.controls.update();
  const sel = document.getElementById("controller");
  META.controllers.forEach((c, i) => { const o = document.createElement("option"); o.value = String(i); o.textContent = c.name; sel.appendChild(o); });
  sel.addEventListener("change", () => selectController(parseInt(sel.value, 10)));
  const slider = document.getElementById("time"); slider.max = String(F - 1);
  slider.addEventListener("input", () => show(parseInt(slider.value, 10)));
  const play = document.getElementById("play");
  play.addEventListener("click", () => { playing = !playing; play.textContent = playing ? "Pause" : "Play"; if (playing) requestAnimationFrame(tick); });
  document.getElementById("note").textContent = "— " + META.note;
  document.getElementById("legend").innerHTML = '<span style="color:#1b9e3a">━ desired path</span><span style="color:#d81b60">● end effector</span><span>arm glows red as σmin drops below σS</span>';
  document.getElementById("warn").textContent = META.warnings.join(" ");
  selectController(0); show(0);
  readHash(); window.addEventListener("hashchange", readHash);
  window.replayReady = true;
}
main().catch(e => { console.error("replay failed: " + e); document.getElementById("warn").textContent = "replay failed: " + e; });
</script></body></html>
"""
