"""Benchmark: the depth cue of the renders (shadow map or SSAO) and what each costs, offscreen.

For each offscreen OpenGL that VTK can use here (EGL and OSMesa, both Mesa's llvmpipe on the
CPU) and each way of darkening what is hidden from the light:

* ``none``: no shadows;
* ``shadow_map``: the renderer's passes (:func:`pipeline.render.actors.shadow_passes`): bake the key
  light's shadow map, draw the opaque geometry once with shadows;
* ``shadow_map_pyvista``: PyVista's ``enable_shadows`` (the same two passes after a full opaque
  render, which it keeps);
* ``ssao``: PyVista's ``enable_ssao`` (screen-space ambient occlusion, Bavoil & Sainz 2008);

it measures the CPU seconds per 640x480 frame (``time.process_time`` of the process, llvmpipe's
threads included; robust to other processes on a shared machine) on a liquid surface of a
dam-break run (the frames of ``--run``, by default a small run made here), and the contrast of
the contact cue: the floor right by a ball resting on it against the floor far from it
(luminance difference, 0-255; what ``tests/pipeline/test_render_looks.py`` asserts).  It also
times the shadow map at supersampling 1, 1.5 and 2 (the renderer's anti-aliasing).

Each (window, method) runs in its own process, pinned like the caller.  Run it alone::

    python benchmarks/bench_render.py [--run outputs/dam_break]

Writes ``benchmarks/results/render.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results" / "render.json"
WINDOWS = {"egl": "vtkEGLRenderWindow", "osmesa": "vtkOSOpenGLRenderWindow"}
METHODS = ("none", "shadow_map", "shadow_map_pyvista", "ssao")


def _configure(renderer, method: str) -> None:
    """Switch a shadowed :class:`pipeline.render.renderer.Renderer` to ``method``."""
    if method == "shadow_map":
        return
    renderer._scene.SetPass(None)
    if renderer._passes is not None:
        renderer._passes.ReleaseGraphicsResources(renderer.plotter.render_window)
        renderer._passes = None
    if method == "shadow_map_pyvista":
        renderer.plotter.enable_shadows()
        baker = renderer.plotter.renderer._render_passes._shadow_map_pass.GetShadowMapBakerPass()
        from pipeline.render import looks

        baker.SetResolution(looks.SHADOW_MAP_RESOLUTION)
        baker.SetExponentialConstant(looks.SHADOW_EXPONENT)
    elif method == "ssao":
        renderer.plotter.enable_ssao(radius=0.1 * renderer.radius, bias=0.002 * renderer.radius,
                                     kernel_size=64, blur=True)


def _ball_scene(folder: Path) -> Path:
    import pyvista as pv

    from filters.geometry import Plane
    from pipeline.io.colliders import COLLIDERS_FILE, Collider, write_colliders
    from pipeline.io.series import SeriesWriter

    ball = pv.Sphere(radius=0.1, center=(0.0, 0.0, 0.1), theta_resolution=48, phi_resolution=48)
    writer = SeriesWriter(folder / "jello.pvd")
    writer.write(ball, 0.0)
    write_colliders([Collider("floor", Plane((0, 0, 0), (0, 0, 1)), "floor")],
                    folder / COLLIDERS_FILE)
    return folder / "jello.pvd"


def _contrast(renderer, image) -> float:
    """Mean luminance of the floor far from the ball minus that right by it, on the side away
    from the key light (floor pixels only: the ball's own pixels are left out by their hue)."""
    import math

    import numpy as np

    key = np.array(renderer._key.position)
    away = math.atan2(-key[1], -key[0])
    angles = away + np.radians(np.arange(-30, 31, 10))

    def ring(d):
        return renderer.pixels_of([[d * math.cos(a), d * math.sin(a), 0.0] for a in angles])

    lum = image.astype(float).mean(axis=-1)

    def floor_mean(pixels):
        values = []
        for c, r in np.round(pixels).astype(int):
            if 0 <= r < image.shape[0] and 0 <= c < image.shape[1] and \
                    abs(int(image[r, c, 0]) - int(image[r, c, 2])) < 25:
                values.append(lum[r, c])
        return float(np.mean(values)) if values else float("nan")

    return floor_mean(ring(-0.3)) - floor_mean(ring(0.125))


def measure(method: str, run: Path, frames: int, supersample: float) -> dict:
    """In this process: CPU s per frame of ``run``'s surface and the ball's contrast."""
    import pipeline.render.renderer as renderer_module

    renderer_module.SUPERSAMPLE = supersample
    from pipeline.render.renderer import Renderer

    with tempfile.TemporaryDirectory() as tmp:
        with Renderer(_ball_scene(Path(tmp)), size=(240, 180), text=False,
                      bounds=(-0.4, 0.4, -0.4, 0.4, 0.0, 0.25)) as renderer:
            _configure(renderer, method)
            contrast = _contrast(renderer, renderer.render(0, 0.0))
    series = [run / "particles.pvd", run / "surface.pvd"]
    with Renderer(series, size=(640, 480)) as renderer:
        window = renderer.plotter.render_window.GetClassName()
        _configure(renderer, method)
        n = len(renderer.times)
        picks = [round(k * (n - 1) / max(frames - 1, 1)) for k in range(frames)]
        renderer.render(picks[0], 0.0)  # shaders compiled
        start = time.process_time()
        for k, index in enumerate(picks):
            renderer.render(index, 360.0 * k / frames)
        per_frame = (time.process_time() - start) / len(picks)
    return {"window": window, "method": method, "supersample": supersample,
            "cpu_s_per_frame": round(per_frame, 3), "contrast": round(contrast, 1)}


def _small_run(folder: Path) -> Path:
    from pipeline.cli import main as blobflow

    code = blobflow(["run", "dam_break", "--set", "spacing=0.008", "--frames", "16",
                     "--out", str(folder), "--no-render", "-q"])
    if code != 0:
        raise RuntimeError("the dam-break run failed")
    return folder


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, help="a dam_break run folder (particles, surface)")
    parser.add_argument("--frames", type=int, default=6, help="frames timed per case")
    parser.add_argument("--child", nargs=3, metavar=("METHOD", "RUN", "SUPERSAMPLE"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        method, run, ss = args.child
        print(json.dumps(measure(method, Path(run), args.frames, float(ss))))
        return {}
    with tempfile.TemporaryDirectory(prefix="blobflow-bench-render-") as tmp:
        run = args.run or _small_run(Path(tmp) / "dam_break")
        cases = [(w, m, 1.5) for w in WINDOWS for m in METHODS]
        cases += [("egl", "shadow_map", ss) for ss in (1.0, 2.0)]
        rows = []
        for window, method, ss in cases:
            env = dict(os.environ, VTK_DEFAULT_OPENGL_WINDOW=WINDOWS[window])
            env.pop("DISPLAY", None)
            out = subprocess.run([sys.executable, __file__, "--frames", str(args.frames),
                                  "--child", method, str(run), str(ss)], env=env,
                                 capture_output=True, text=True, check=True)
            row = json.loads(out.stdout.strip().splitlines()[-1])
            rows.append(row)
            print(f"{window:7s} {method:19s} ss {ss:<4g} {row['cpu_s_per_frame']:6.3f} s/frame  "
                  f"contrast {row['contrast']:6.1f}", flush=True)
        with open(run / "surface.pvd") as f:
            surface_frames = f.read().count("<DataSet")
    result = {
        "benchmark": "render",
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version()},
        "run": str(args.run) if args.run else "dam_break spacing=0.008, 16 frames (made here)",
        "surface_frames": surface_frames,
        "frames_timed": args.frames,
        "size": [640, 480],
        "note": "CPU seconds per frame (process time, llvmpipe's threads included) on the "
                "liquid surface with its tank; contrast = floor far from a resting ball minus "
                "floor right by it (luminance 0-255), higher = clearer contact shadow",
        "cases": rows,
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    main()
