"""An interactive 3D viewer of a run as one self-contained HTML file: no Jupyter widgets, no
network, nothing to install. ``gs.viz.view(res, "grasp.html")`` (or ``write_viewer``).

The file holds the surfaces' meshes once, in their own frames, and the motion as one pose per
frame (the object's rotation and position, each fingertip's, the joints, the contact points),
as JSON; a small script draws them on a canvas. Drag to turn the view, scroll to zoom, the
slider or the play button to move in time. ``grasp.html#frame=-1`` opens at the last frame.

Every string that reaches the page (the scene's name, the run's method, read from a shared
``.npz`` perhaps) is escaped: HTML-escaped in the title, and in the JSON inside ``<script>``
with ``<``, ``>``, ``&``, U+2028 and U+2029 as ``\\uXXXX`` escapes, so no text of a result
can close the script or open another (``_page``).
"""
from __future__ import annotations

import html
import json
import math
import numbers
import re
from pathlib import Path

import numpy as np

from grasping_sym.errors import ViewOptionError
from grasping_sym.viz.options import check_scene
from grasping_sym.viz.plots3d import geometry_at, geometry_function, surface_mesh

#: Frames written by default (evenly spaced in time).
FRAMES = 150
#: Bounds of ``frames`` (at most the result's samples are used) and of ``fps`` (frames per
#: second of the play button).
MIN_FRAMES, MAX_FRAMES = 2, 5000
MAX_FPS = 240.0
#: Mesh lines per direction of a surface.
MESH = 24

_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
body { margin: 0; font: 13px sans-serif; background: #ffffff; color: #222; }
#bar { position: absolute; left: 8px; bottom: 8px; right: 8px; display: flex; gap: 8px;
       align-items: center; }
#t { flex: 1; } canvas { display: block; }
#info { position: absolute; left: 8px; top: 6px; }
</style></head><body>
<canvas id="c"></canvas>
<div id="info"></div>
<div id="bar"><button id="play">play</button><input id="t" type="range" min="0" value="0">
<span id="time"></span></div>
<script>
const D = __DATA__;
const cv = document.getElementById("c"), g = cv.getContext("2d");
const slider = document.getElementById("t"), play = document.getElementById("play");
slider.max = D.frames.length - 1;
let yaw = 0.6, pitch = 0.45, zoom = 1.0, k = 0, running = false, drag = null;
function size() { cv.width = window.innerWidth; cv.height = window.innerHeight; draw(); }
function mul(R, v) { return [R[0]*v[0]+R[1]*v[1]+R[2]*v[2], R[3]*v[0]+R[4]*v[1]+R[5]*v[2],
                             R[6]*v[0]+R[7]*v[1]+R[8]*v[2]]; }
function view(p) {
  // the vertical axis up, turned by yaw about it and tilted by pitch
  const c = [p[0]-D.centre[0], p[1]-D.centre[1], p[2]-D.centre[2]];
  const u = D.up, a = [c[(u+1)%3], c[u], c[(u+2)%3]];
  const x = Math.cos(yaw)*a[0] - Math.sin(yaw)*a[2], z0 = Math.sin(yaw)*a[0] + Math.cos(yaw)*a[2];
  const y = Math.cos(pitch)*a[1] - Math.sin(pitch)*z0, z = Math.sin(pitch)*a[1] + Math.cos(pitch)*z0;
  const s = zoom * 0.42 * Math.min(cv.width, cv.height) / D.radius;
  return [cv.width/2 + s*x, cv.height*0.47 - s*y, z];
}
function place(R, c, v) { const w = mul(R, v); return [w[0]+c[0], w[1]+c[1], w[2]+c[2]]; }
function mesh(m, R, c, colour) {
  g.strokeStyle = colour; g.lineWidth = 1;
  const pts = m.points.map(v => view(place(R, c, v))), n = m.n;
  g.beginPath();
  for (let i = 0; i < n; i++) for (let j = 0; j < n; j++) {
    const p = pts[i*n+j];
    if (j < n-1) { const q = pts[i*n+j+1]; g.moveTo(p[0], p[1]); g.lineTo(q[0], q[1]); }
    if (i < n-1) { const q = pts[(i+1)*n+j]; g.moveTo(p[0], p[1]); g.lineTo(q[0], q[1]); }
  }
  g.stroke();
}
function draw() {
  const f = D.frames[k];
  g.fillStyle = "#ffffff"; g.fillRect(0, 0, cv.width, cv.height);
  mesh(D.object, f.R, f.pos, "rgba(214,39,40,0.75)");
  f.tips.forEach((t, i) => mesh(D.tips[i], t.R, t.c, D.colours[i % D.colours.length]));
  g.strokeStyle = "#444"; g.lineWidth = 5; g.lineCap = "round";
  f.joints.forEach(chain => { g.beginPath(); chain.forEach((p, j) => { const q = view(p);
    if (j === 0) g.moveTo(q[0], q[1]); else g.lineTo(q[0], q[1]); }); g.stroke(); });
  g.fillStyle = "#000";
  f.contacts.forEach(p => { const q = view(p); g.beginPath(); g.arc(q[0], q[1], 4, 0, 6.3); g.fill(); });
  slider.value = k;
  document.getElementById("time").textContent = "t = " + D.times[k].toFixed(3) + " s";
  document.getElementById("info").textContent = D.title + " (drag to turn, scroll to zoom)";
}
function tick() { if (!running) return; k = (k + 1) % D.frames.length; draw();
                  setTimeout(() => requestAnimationFrame(tick), 1000 / D.fps); }
play.onclick = () => { running = !running; play.textContent = running ? "pause" : "play"; tick(); };
slider.oninput = () => { k = +slider.value; draw(); };
cv.onmousedown = e => { drag = [e.clientX, e.clientY, yaw, pitch]; };
window.onmouseup = () => { drag = null; };
window.onmousemove = e => { if (!drag) return; yaw = drag[2] + (e.clientX - drag[0]) * 0.01;
  pitch = Math.max(-1.5, Math.min(1.5, drag[3] + (e.clientY - drag[1]) * 0.01)); draw(); };
cv.onwheel = e => { e.preventDefault(); zoom *= Math.exp(-e.deltaY * 0.001); draw(); };
window.onresize = size;
const h = location.hash.match(/frame=(-?[0-9]+)/);   // e.g. grasp.html#frame=-1: the last frame
if (h) { const n = D.frames.length; k = ((+h[1]) % n + n) % n; }
size();
</script></body></html>
"""


def write_viewer(result, path: str | Path, scene=None, *, frames: int = FRAMES, fps: float = 25.0) -> Path:
    """Write the viewer of ``result`` (a 3D scene's run) to ``path`` (``.html``).

    Parameters
    ----------
    frames
        Poses written, evenly spaced over the run: an integer in ``[MIN_FRAMES, MAX_FRAMES]``
        (2 ... 5000; at most the result's samples are used).
    fps
        Frames per second when playing: in ``(0, MAX_FPS]`` (240).

    Raises
    ------
    ViewOptionError
        An option out of its bounds, no 3D scene, another suffix than ``.html``, or a result of
        one sample.
    """
    check_options(frames=frames, fps=fps)
    scene = scene if scene is not None else getattr(result, "scene", None)
    if scene is None:
        raise ViewOptionError("the viewer needs the run's scene: pass scene=..., or run a model made "
                              "by gs.build(scene) (a model from gs.load, or a loaded result, has none)")
    if scene.dimension != 3:
        raise ViewOptionError("the viewer draws 3D scenes: for a 2D run use gs.viz.animate(res, 'motion.gif')")
    check_scene(result, scene, "view")
    path = Path(path)
    if path.suffix != ".html":
        raise ViewOptionError(f"{path.name}: the viewer is an .html file")
    if len(result.t) < 2:
        raise ViewOptionError("a result of one sample does not move: simulate with more output times")

    rows = np.unique(np.linspace(0, len(result.t) - 1, min(int(frames), len(result.t))).astype(int))
    geos = geometry_at(geometry_function(scene), scene, result, rows)

    def grid(surface, n):
        m = surface_mesh(surface, n=n)
        return {"n": int(m.shape[0]), "points": np.round(m.reshape(-1, 3), 7).tolist()}

    def rot(R):
        return np.round(np.asarray(R, float).reshape(3, 3), 9).ravel().tolist()

    out_frames, every = [], []
    for geo in geos:
        chains = [np.asarray(geo[f"joints{i}"], float).reshape(3, -1).T
                  for i in range(1, len(scene.fingers) + 1)]
        tips = [{"R": rot(geo[f"Pi{i}"]), "c": chains[i - 1][-1].round(7).tolist()}
                for i in range(1, len(scene.fingers) + 1)]
        contacts = [np.asarray(geo[f"p_o{i}"], float).ravel().round(7).tolist()
                    for i in range(1, scene.n_contacts + 1)]
        out_frames.append({"R": rot(geo["R"]), "pos": np.asarray(geo["pos"], float).ravel().round(7).tolist(),
                           "tips": tips, "joints": [c.round(7).tolist() for c in chains],
                           "contacts": contacts})
        every += [np.asarray(geo["pos"], float).ravel(), *chains]
    pts = np.vstack([np.atleast_2d(p) for p in every])
    gdir = scene.gravity if scene.gravity and any(scene.gravity) else (0.0, -1.0, 0.0)
    up = int(np.argmax(np.abs(gdir)))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid = (lo + hi) / 2
    data = {"title": f"{scene.name}: {result.method}, t = 0 ... {result.t[-1]:.3g} s",
            "times": [float(result.t[r]) for r in rows], "frames": out_frames, "fps": float(fps),
            "object": grid(scene.object_surface, MESH),
            "tips": [grid(f.tip, MESH // 2) for f in scene.fingers],
            "colours": ["rgba(31,119,180,0.8)", "rgba(44,160,44,0.8)", "rgba(148,103,189,0.8)"],
            "up": up, "centre": [float(v) for v in mid],
            "radius": float(0.5 * np.max(hi - lo)) or 0.05}
    page = _page(str(scene.name), data)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path


def check_options(*, frames: int = FRAMES, fps: float = 25.0) -> None:
    """Refuse, by name and with its bounds, a ``frames`` or ``fps`` the viewer cannot write."""
    if not isinstance(frames, numbers.Integral) or isinstance(frames, bool) or \
            not MIN_FRAMES <= frames <= MAX_FRAMES:
        raise ViewOptionError(f"frames = {frames!r}: give a whole number of poses from {MIN_FRAMES} "
                              f"to {MAX_FRAMES} (default {FRAMES})")
    if not isinstance(fps, numbers.Real) or isinstance(fps, bool) or not math.isfinite(fps) or \
            not 0 < fps <= MAX_FPS:
        raise ViewOptionError(f"fps = {fps!r}: give frames per second in (0, {MAX_FPS:g}] "
                              "(default 25)")


#: What a JSON text inside ``<script>`` must not hold as such: ``</script>`` or ``<!--`` would
#: end or change the script element, and U+2028/U+2029 end a line in older JavaScript.
_SCRIPT_UNSAFE = str.maketrans({"<": "\\u003c", ">": "\\u003e", "&": "\\u0026",
                                "\u2028": "\\u2028", "\u2029": "\\u2029"})


def script_json(data) -> str:
    """``data`` as JSON that is safe inside an HTML ``<script>`` element, and the same value
    to JavaScript: the unsafe characters occur only inside JSON strings, where their
    ``\\uXXXX`` escapes stand for them."""
    return json.dumps(data).translate(_SCRIPT_UNSAFE)


def _page(title: str, data: dict) -> str:
    """The page: ``title`` HTML-escaped, ``data`` as script-safe JSON, both put in one pass
    (a title that holds ``__DATA__`` stays text)."""
    parts = {"TITLE": html.escape(title), "DATA": script_json(data)}
    return re.sub(r"__(TITLE|DATA)__", lambda m: parts[m.group(1)], _PAGE)
