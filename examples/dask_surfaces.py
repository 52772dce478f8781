"""
Surfaces of many frames on a Dask cluster
=========================================

Reconstructing the surface of a particle series is one independent task per frame.
:func:`pipeline.surface.frames.surface_series` runs them serially, or on a Dask cluster given as
``client=``: each frame is written atomically, the collection once all frames are done, a
failed task is retried, and ``resume=True`` computes only what is missing.  Serial and parallel
runs write byte-identical files.  (``blobflow surface PARTICLES.pvd --workers N`` is the same
from the command line.)

Here the ``drop`` scene (a ball of liquid falling into a pool) writes its particles only, and a
local cluster of two single-threaded worker processes rebuilds the surfaces.  Dask starts its
workers by importing this script again, so the work runs under ``if __name__ == "__main__":``.
Install Dask with ``pip install -e ".[dask]"``.
"""

# %%
import os
from pathlib import Path

import pyvista as pv

from pipeline.render import render_still
from pipeline.scene import load_scene
from pipeline.surface import surface_series
from pipeline.surface.options import liquid_surface_options

pv.OFF_SCREEN = True  # draw without a display

SMALL = os.environ.get("BLOBFLOW_EXAMPLE_SMALL") == "1"  # the tests run every example small
OUT = Path(os.environ.get("BLOBFLOW_EXAMPLES_OUT", "outputs/examples")) / "dask_surfaces"

# %%
# The particles
# -------------
# The scene's defaults (about 2,500 particles 12 mm apart in a tank 24 x 24 x 30 cm) without
# its own surface, for 0.6 s.


def simulate():
    flow = load_scene("drop").build(surface=False)
    flow.source.set_frames(fps=30, duration=0.2 if SMALL else 0.6)
    return flow.run(OUT, progress=False)["particles"]  # OUT/particles.pvd


# %%
# The surfaces, on the cluster
# ----------------------------
# The options are those of :func:`pipeline.surface.surface_stages`; for a liquid in a tank,
# :func:`~pipeline.surface.options.liquid_surface_options` gives the scenes' own surface (the
# particle radius from the spacing, the surface cut at the tank's walls).


def surfaces(particles):
    from dask.distributed import Client, LocalCluster

    options = liquid_surface_options(0.012, (0.0, 0.0, 0.0), (0.24, 0.24, 0.3))
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        result = surface_series(particles, OUT / "surface.pvd", client=client, progress=False,
                                **options)
    print(f"{result.computed} frames written to {result.path} by "
          f"{len(result.peak_memory)} worker processes")
    return result.path


# %%
# The picture
# -----------
# The most interesting frame (the largest water surface: the splash) drawn with the tank
# (``colliders.vtp``, which the run wrote beside the series).

if __name__ == "__main__":
    surface = surfaces(simulate())
    render_still(surface, OUT / "dask_surfaces.png", size=(800, 600))
