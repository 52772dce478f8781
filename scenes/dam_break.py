"""``dam_break``: a water column collapsing in a closed tank (DFSPH by default, Bender &
Koschier 2017; or WCSPH, Becker & Teschner 2007).

The classic experiment of Martin & Moyce (1952): a column of width ``a`` and height ``2 a`` stands
against the left wall of a tank ``>= 4 a`` long; the front runs along the floor, hits the far
wall, climbs it and falls back as a plunging wave.  The particle series carries ``velocity``
(m/s), ``density`` (kg/m^3), ``pressure`` (Pa) and ``id``.
"""

from __future__ import annotations

from filters.geometry import Box
from filters.sph.scenarios import dam_break_liquid
from filters.validation import check_choice
from pipeline import Flow, SimulationSource
from pipeline.scene import Scene

from .liquid_solver import solver_options
from .liquid_surface import add_liquid_surface

SCENE_FPS = 30.0
SCENE_DURATION = 1.5  # s: collapse, run-up on the far wall, plunging wave, sloshing
#: The tank's free-slip faces for each ``wall_friction`` (the others are no-slip).
WALL_FRICTION = {"all": (), "floor": ("x", "y", "z+"), "none": ("x", "y", "z")}


def build(*, column_width: float = 0.1, column_height: float = 0.2, tank_length: float = 0.4,
          depth: float = 0.1, tank_height: float = 0.3, spacing: float = 0.004,
          viscosity: float = 0.05, kinematic_viscosity: float = 4e-4, xsph: float = 0.0,
          surface_tension: float = 0.0, solver: str = "dfsph", max_density_error: float = 0.001,
          max_iterations: int = 100, cfl: float = 0.4, max_dt: float = 0.005,
          speed_of_sound: float = 0.0, wall_friction: str = "all", surface: bool = True,
          smooth_iterations: int = 30,
          feature_smoothing: int = 25, anisotropic: bool = True) -> Flow:
    """Build the dam-break flow (31,250 fluid particles with the defaults, 25 across the column).

    Parameters
    ----------
    column_width : float
        Width ``a`` of the water column along x (m), > 0.
    column_height : float
        Height of the column (m), normally ``2 a``; at most ``tank_height``.
    tank_length : float
        Inner length of the tank along x (m), >= ``column_width`` (the experiment uses >= 4 a).
    depth : float
        Inner depth of the tank along y (m); the column spans it.
    tank_height : float
        Inner height of the closed tank (m), >= ``column_height``.
    spacing : float
        Particle spacing (m), > 0 and at most half the column's smallest side.  Halving it
        multiplies the particle count by 8 and the run time by about 16.
    viscosity : float
        Monaghan's artificial viscosity ``alpha`` in [0, 1] (WCSPH, and DFSPH when
        ``kinematic_viscosity`` is 0: then ``nu = alpha c h / 20``, which shrinks with the
        spacing).
    kinematic_viscosity : float
        DFSPH: kinematic viscosity ``nu`` (m^2/s) in [0, 1] of the liquid and against the faces
        that ``wall_friction`` names (Weiler et al. 2018's implicit viscosity), the same at every
        spacing; 0 for the one ``viscosity`` gives.  The default, 4e-4 m^2/s, is what
        ``viscosity`` 0.05 gives at the default spacing: an effective viscosity (400 times
        water's) standing for what slows the experiment's surge, friction on the floor and the
        gate's release.
    wall_friction : {"all", "floor", "none"}
        Which tank faces hold the liquid back (no-slip with ``kinematic_viscosity``; the others
        are free-slip): every face (default), the floor alone, or none.  Against Martin &
        Moyce (1952) at a / 10, a / 25 and a / 50, full depth and quasi-2D
        (``benchmarks/results/dam_break_validation.json``): with every face no-slip the surge
        front stays within 4.6 % on average over 0.8 <= T <= 3, but the column's own wall holds
        a viscous film (about ``sqrt(nu t)``, 9 mm at T = 3 with the default ``nu``) that finer
        spacings resolve, so the residual height at that wall comes out 1.7-3.4 % high at a / 10
        and 13-20 % at a / 50; with the floor alone the front stays within 5.4 % and the height
        within 2.2 %, but the liquid sloshes much longer (1.7x the steps over the scene's 1.5 s:
        3.7 m/s up the far wall instead of 2.1); without any friction the front runs 8-12 %
        ahead (at the experiment's speed, but 11-17 ms early: a release that took time in the
        experiment).
    xsph : float
        XSPH velocity smoothing in [0, 1).
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
    check_choice("wall_friction", wall_friction, tuple(WALL_FRICTION))
    simulation = dam_break_liquid(
        column_width=column_width, column_height=column_height, tank_length=tank_length,
        depth=depth, tank_height=tank_height, spacing=spacing,
        free_slip=WALL_FRICTION[wall_friction], viscosity=viscosity, xsph=xsph,
        surface_tension=surface_tension, solver=solver,
        **solver_options(solver, max_density_error, max_iterations, speed_of_sound,
                         kinematic_viscosity),
        cfl=cfl, max_dt=max_dt)
    flow = Flow(SimulationSource(simulation, fps=SCENE_FPS, duration=SCENE_DURATION))
    tank = Box((0.0, 0.0, 0.0), (tank_length, depth, tank_height))  # the tank's inner box
    flow.add_collider("tank", ~tank, role="container")
    if surface:
        add_liquid_surface(flow, spacing=spacing, tank_lo=tank.lower, tank_hi=tank.upper,
                           smooth_iterations=smooth_iterations,
                           feature_smoothing=feature_smoothing, anisotropic=anisotropic)
    return flow


SCENE = Scene("dam_break", build, "a water column collapsing in a closed tank (DFSPH liquid)",
              fps=SCENE_FPS, duration=SCENE_DURATION)
