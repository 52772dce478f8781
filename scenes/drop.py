"""``drop``: a sphere of liquid falling into a resting pool (DFSPH by default, Bender &
Koschier 2017; or WCSPH, Becker & Teschner 2007).

The particle series carries ``velocity`` (m/s), ``density`` (kg/m^3), ``pressure`` (Pa) and
``id`` (the pool's particles first, then the drop's).
"""

from __future__ import annotations

from filters.geometry import Box
from filters.sph.scenarios import drop_liquid
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene

from .liquid_solver import solver_options
from .liquid_surface import add_liquid_surface

SCENE_FPS = 30.0
SCENE_DURATION = 1.5


def build(*, tank_length: float = 0.24, tank_width: float = 0.24, tank_height: float = 0.3,
          pool_depth: float = 0.05, drop_radius: float = 0.04, drop_height: float = 0.2,
          drop_speed: float = 0.0, spacing: float = 0.012, viscosity: float = 0.05,
          kinematic_viscosity: float = 0.0, surface_tension: float = 0.0, solver: str = "dfsph",
          max_density_error: float = 0.001,
          max_iterations: int = 100, cfl: float = 0.4, max_dt: float = 0.005,
          speed_of_sound: float = 0.0, surface: bool = True, smooth_iterations: int = 30,
          feature_smoothing: int = 25, anisotropic: bool = True) -> Flow:
    """Build the drop flow (about 1,750 fluid particles with the defaults).

    Parameters
    ----------
    tank_length : float
        Inner length of the closed tank along x (m).
    tank_width : float
        Inner width of the tank along y (m).
    tank_height : float
        Inner height of the tank (m).
    pool_depth : float
        Depth of the resting pool (m): 0, or at least two spacings.
    drop_radius : float
        Radius of the falling sphere (m), at least one spacing.
    drop_height : float
        Height of the sphere's centre above the floor (m) at t = 0.
    drop_speed : float
        Initial downward speed of the sphere (m/s), >= 0.
    spacing : float
        Particle spacing (m), > 0.
    viscosity : float
        Monaghan's artificial viscosity ``alpha`` in [0, 1] (DFSPH: ``nu = alpha c h / 20``
        unless ``kinematic_viscosity`` is given).
    kinematic_viscosity : float
        DFSPH: kinematic viscosity (m^2/s) in [0, 1] of the liquid and against the walls; 0
        (default) for the one ``viscosity`` gives.
    surface_tension : float
        Akinci et al. (2013) surface tension coefficient, >= 0.
    solver : {"dfsph", "wcsph"}
        Pressure solver: divergence-free SPH (default; implicit pressure, steps from the
        velocity CFL, implicit viscosity) or weakly compressible SPH (Tait equation of state).
    max_density_error : float
        DFSPH tolerance of the mean compression, in [1e-6, 0.1] (0.001 = 0.1 %).
    max_iterations : int
        DFSPH: most iterations of each pressure solve, in [2, 10000].
    cfl : float
        Courant number of the adaptive time step, in (0, 1].
    max_dt : float
        Largest time step (s), in (0, 1]; DFSPH also keeps its steps where its density solve
        converges in a few iterations.
    speed_of_sound : float
        WCSPH: speed of sound (m/s) of the Tait equation of state, > 0, or 0 for ten times the
        largest expected speed ``sqrt(2 g H)``.
    surface : bool
        Also write the reconstructed water surface (``surface.pvd``).
    smooth_iterations : int
        Windowed-sinc smoothing iterations of the surface (0 to 1000).
    feature_smoothing : int
        Feature-weighted Laplacian smoothing sweeps of the surface (0 to 10000): flat water
        smoothed, droplets and sheets kept (see ``scenes/liquid_surface.py``).
    anisotropic : bool
        Surface from anisotropic kernels (Yu & Turk 2013), about 1.35x the reconstruction
        time: flat water up to 2x flatter (as flat on one SPH pool); drops keep their volume
        either way (see ``scenes/liquid_surface.py``); ``false`` for isotropic kernels.
    """
    simulation = drop_liquid(
        tank_length=tank_length, tank_width=tank_width, tank_height=tank_height,
        pool_depth=pool_depth, drop_radius=drop_radius, drop_height=drop_height,
        drop_speed=drop_speed, spacing=spacing, viscosity=viscosity,
        surface_tension=surface_tension, solver=solver,
        **solver_options(solver, max_density_error, max_iterations, speed_of_sound,
                         kinematic_viscosity),
        cfl=cfl, max_dt=max_dt)
    flow = Flow(SimulationSource(simulation, fps=SCENE_FPS, duration=SCENE_DURATION))
    tank = Box((0.0, 0.0, 0.0), (tank_length, tank_width, tank_height))  # the tank's inner box
    flow.add_collider("tank", ~tank, role="container")
    if surface:
        add_liquid_surface(flow, spacing=spacing, tank_lo=tank.lower, tank_hi=tank.upper,
                           smooth_iterations=smooth_iterations,
                           feature_smoothing=feature_smoothing, anisotropic=anisotropic)
    return flow


SCENE = Scene("drop", build, "a sphere of liquid falling into a resting pool (DFSPH liquid)",
              fps=SCENE_FPS, duration=SCENE_DURATION)
