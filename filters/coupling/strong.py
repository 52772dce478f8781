"""Rigid bodies inside the liquid's density solve: the pressure that holds the liquid up moves
the bodies it pushes, within the same iterations.

With the bodies' boundary particles moving at the velocity the bodies start the step with, the
density solve finds the pressure that keeps the liquid incompressible around bodies that do not
yield; the bodies then take that force and move with it, and the next step's liquid meets them
where the last step did not expect them.  A floating body alternates from step to step (the
coupled benchmark's 500 kg/m^3 box: +0.016 / -0.005 m/s on alternate steps, one step in four
needing more than 20 density iterations).  Gissler et al. (2019), "Interlinked SPH pressure
solvers for strong fluid-rigid coupling" (ACM TOG 38(1)), put the bodies inside the pressure
solve; this module does so in the form of :mod:`filters.sph.dfsph`'s Jacobi sweeps.

In every sweep of the density solve the pressures of the fluid particles next to a rigid body
give the body a force and a torque (the same pairs and the same wall pressures as
:func:`filters.sph.boundary_set.boundary_forces`), hence, with gravity and the divergence
solve's pressure of this step, an acceleration ``A_B`` and an angular acceleration
``alpha_B = I_B^-1 tau_B`` (world frame).  A boundary particle ``b`` of the body then moves with
``v_b + dt (A_B + alpha_B x r_b)``, which changes a neighbour's predicted density by
``dt^2 sum_b V_b (A_B + alpha_B x r_b) . grad W_ib = dt^2 (A_B . G_iB + alpha_B . T_iB)``, with
``G_iB = sum_{b in B} V_b grad W_ib`` and ``T_iB = sum_{b in B} V_b r_b x grad W_ib`` fixed
within the step: the sweep's sources (the density source and the wall constraints' slack) get
that term.  The liquid's step then assumes the motion the body makes with the force the liquid
gives it.  Fixed bodies, elastic bodies and walls keep their velocities within the solve.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..kernels import kernel_dw
from ..sph.dfsph_kernels import NO_WALL
from ..sph.neighbourhood import cell_range, wall_key, wall_of

if TYPE_CHECKING:
    from ..sph.dfsph import DFSPHSolver
    from ..sph.liquid import SPHLiquid

__all__ = ["RigidLink", "SLOTS"]

#: Slots (a body and one of its walls as a particle sees it) per fluid particle; a further wall
#: of a body goes into one of that body's slots, a further body is left out of the particle's
#: sources (five walls or bodies within one kernel support: not met in the scenes).
SLOTS = 4


@njit(cache=True, error_model="numpy")
def _build(sel, owner, xb, volb, nrmb, centers, x, start, origin, cell, dims, h, kind, ncl, cn,
           nslot, sbody, skey, sgt, touched, ntouched, vv, vb, fvolb, nu_b, mass, visc, lost):
    """``G_iB`` and ``T_iB`` per fluid particle ``i`` and (body, wall) slot; returns how many
    fluid particles have a slot (listed in ``touched``).  Adds to ``visc`` (B, 6) the force and
    torque of the liquid's viscosity on the bodies, with the fluid velocities ``vv`` after the
    viscosity solve (the boundary term of :func:`filters.sph.boundary_set.boundary_forces`),
    and to ``lost[0]`` the pairs left out of the slots (a fifth body or wall of a particle)."""
    for t in range(ntouched):
        nslot[touched[t]] = 0
    n = x.shape[0]
    cap = sbody.shape[1]
    h2 = h * h
    eps = 0.01 * 0.25 * h2
    inv = 1.0 / cell
    nt = 0
    if n == 0:
        return 0
    for q in range(sel.shape[0]):
        b = sel[q]
        body = owner[q]
        qx = xb[b, 0]
        qy = xb[b, 1]
        qz = xb[b, 2]
        rx = qx - centers[body, 0]
        ry = qy - centers[body, 1]
        rz = qz - centers[body, 2]
        x0, x1 = cell_range(qx, origin[0], inv, dims[0])
        y0, y1 = cell_range(qy, origin[1], inv, dims[1])
        z0, z1 = cell_range(qz, origin[2], inv, dims[2])
        viscous = nu_b > 0.0 and fvolb[b] > 0.0
        fx = 0.0
        fy = 0.0
        fz = 0.0
        for iz in range(z0, z1 + 1):
            for iy in range(y0, y1 + 1):
                row = (iz * dims[1] + iy) * dims[0]
                for i in range(start[row + x0], start[row + x1 + 1]):
                    dx = x[i, 0] - qx
                    dy = x[i, 1] - qy
                    dz = x[i, 2] - qz
                    r2 = dx * dx + dy * dy + dz * dz
                    if r2 >= h2 or r2 == 0.0:
                        continue
                    r = np.sqrt(r2)
                    dw = kernel_dw(kind, r, h) / r
                    if viscous:
                        u = ((vv[i, 0] - vb[b, 0]) * dx + (vv[i, 1] - vb[b, 1]) * dy
                             + (vv[i, 2] - vb[b, 2]) * dz)
                        c = -mass * 10.0 * nu_b * fvolb[b] * dw * u / (r2 + eps)
                        fx += c * dx
                        fy += c * dy
                        fz += c * dz
                    g = volb[b] * dw  # V_b grad_i W_ib = g (x_i - x_b)
                    gx = g * dx
                    gy = g * dy
                    gz = g * dz
                    k = -1
                    if ncl[i] > 1:  # the wall b counts in (the pass's and the forces' rule)
                        mx, my, mz = wall_key(nrmb[b, 0], nrmb[b, 1], nrmb[b, 2], dx, dy, dz)
                        k = min(wall_of(i, mx, my, mz, ncl[i], cn), ncl[i] - 1)
                    ns = nslot[i]
                    if ns == 0:
                        touched[nt] = i
                        nt += 1
                    s = 0
                    while s < ns and not (sbody[i, s] == body and skey[i, s] == k):
                        s += 1
                    if s == ns:
                        if ns < cap:
                            sbody[i, s] = body
                            skey[i, s] = k
                            for c in range(6):
                                sgt[i, s, c] = 0.0
                            nslot[i] = ns + 1
                        else:  # full: into a slot of the same body, else left out
                            s = cap - 1
                            while s >= 0 and sbody[i, s] != body:
                                s -= 1
                            if s < 0:
                                lost[0] += 1
                                continue
                    sgt[i, s, 0] += gx
                    sgt[i, s, 1] += gy
                    sgt[i, s, 2] += gz
                    sgt[i, s, 3] += ry * gz - rz * gy
                    sgt[i, s, 4] += rz * gx - rx * gz
                    sgt[i, s, 5] += rx * gy - ry * gx
        visc[body, 0] += fx
        visc[body, 1] += fy
        visc[body, 2] += fz
        visc[body, 3] += ry * fz - rz * fy
        visc[body, 4] += rz * fx - rx * fz
        visc[body, 5] += rx * fy - ry * fx
    return nt


@njit(cache=True, error_model="numpy")
def _compact(touched, nt, nslot, sbody, skey, sgt, src, wsrc, rstart, rbody, rkey, rgt, tsrc,
             twsrc):
    """The slots of the particles ``touched[:nt]`` (in that order) as consecutive rows (rows
    ``rstart[t]:rstart[t + 1]`` are particle ``touched[t]``'s), and their sources now."""
    r = 0
    for t in range(nt):
        i = touched[t]
        rstart[t] = r
        tsrc[t] = src[i]
        for k in range(wsrc.shape[1]):
            twsrc[t, k] = wsrc[i, k]
        for s in range(nslot[i]):
            rbody[r] = sbody[i, s]
            rkey[r] = skey[i, s]
            for c in range(6):
                rgt[r, c] = sgt[i, s, c]
            r += 1
    rstart[nt] = r


@njit(cache=True, error_model="numpy")
def _wrench(touched, nt, rstart, rbody, rkey, rgt, p, pw, ncl, walls, mass, out):
    """Add to ``out`` (B, 6) the force and torque of the pressures ``p`` (and the wall pressures
    ``pw`` where ``walls``) on the bodies: ``m (p_i + pw_i0 + pw_ik) (G, T)`` per row."""
    for t in range(nt):
        i = touched[t]
        p0 = p[i]
        if walls and ncl[i] > 0:
            p0 += pw[i, 0]
        for r in range(rstart[t], rstart[t + 1]):
            k = rkey[r]
            q = p0 + (pw[i, k] if walls and k > 0 else 0.0)
            body = rbody[r]
            for c in range(6):
                out[body, c] += mass * q * rgt[r, c]


@njit(cache=True, error_model="numpy")
def _update(touched, nt, rstart, rbody, rkey, rgt, pi, pw, ncl, mass, base, inv_mass,
            inv_inertia, gravity, scale, tsrc, twsrc, src, wsrc, acc):
    """One sweep's sources: the bodies' wrench under ``pi`` and ``pw`` (plus ``base``), their
    accelerations ``acc`` (B, 6: linear, angular), and with them the density sources ``src``
    and wall slacks ``wsrc`` of the particles next to a body (``tsrc``, ``twsrc``: theirs
    without the bodies' motion)."""
    w = base.copy()
    _wrench(touched, nt, rstart, rbody, rkey, rgt, pi, pw, ncl, True, mass, w)
    for b in range(w.shape[0]):
        moving = inv_mass[b] > 0.0
        for c in range(3):
            acc[b, c] = w[b, c] * inv_mass[b] + gravity[c] if moving else 0.0
        for c in range(3):
            acc[b, 3 + c] = (inv_inertia[b, c, 0] * w[b, 3] + inv_inertia[b, c, 1] * w[b, 4]
                             + inv_inertia[b, c, 2] * w[b, 5])
    for t in range(nt):
        i = touched[t]
        for k in range(wsrc.shape[1]):
            wsrc[i, k] = twsrc[t, k]
        beta = 0.0
        for r in range(rstart[t], rstart[t + 1]):
            body = rbody[r]
            bs = 0.0
            for c in range(6):
                bs += acc[body, c] * rgt[r, c]
            beta += bs
            k = rkey[r]
            if k > 0 and twsrc[t, k] < NO_WALL:
                wsrc[i, k] += scale * bs
        src[i] = tsrc[t] + scale * beta
        if twsrc[t, 0] < NO_WALL:
            wsrc[i, 0] += scale * beta


class RigidLink:
    """The rigid bodies of a liquid's boundary inside its density solve (module notes).

    Set as ``DFSPHSolver.link`` by :class:`filters.coupling.Coupled`; the solver calls
    :meth:`begin` once its sources are set up and :meth:`update` before every sweep.

    Parameters
    ----------
    liquid : filters.sph.SPHLiquid
        The DFSPH liquid.
    owner : (M,) int64
        Per boundary particle (in the order the liquid was built with), the rigid body that
        moves it (a number over all the coupled rigid bodies; a fixed body's inverse mass is
        0), or -1 (walls, elastic bodies).
    """

    def __init__(self, liquid: SPHLiquid, owner: np.ndarray):
        self.liquid = liquid
        self.owner = np.ascontiguousarray(owner, dtype=np.int64)
        n_bodies = int(self.owner.max(initial=-1)) + 1
        self.n_bodies = n_bodies
        self.centers = np.zeros((n_bodies, 3))
        self.inv_mass = np.zeros(n_bodies)
        self.inv_inertia = np.zeros((n_bodies, 3, 3))
        self.base = np.zeros((n_bodies, 6))
        self.acc = np.zeros((n_bodies, 6))
        #: The viscous force and torque of the liquid on each body in the step being taken
        #: (B, 6), from :meth:`begin`.
        self.viscous = np.zeros((n_bodies, 6))
        self.lost = np.zeros(1, dtype=np.int64)
        #: Whether :meth:`begin` ran in the step being taken (:meth:`forces` answers).
        self.ready = False
        self._n = -1
        self.count = 0

    def set_bodies(self, centers: np.ndarray, inv_mass: np.ndarray,
                   inv_inertia: np.ndarray) -> None:
        """Where the bodies' centres of mass are (B, 3), their inverse masses (B,) (0: fixed)
        and world inverse inertia tensors (B, 3, 3), for the next step."""
        self.centers[:] = centers
        self.inv_mass[:] = inv_mass
        self.inv_inertia[:] = inv_inertia

    def _allocate(self, n):
        if n != self._n:
            self.nslot = np.zeros(n, dtype=np.int32)
            self.sbody = np.zeros((n, SLOTS), dtype=np.int32)
            self.skey = np.zeros((n, SLOTS), dtype=np.int32)
            self.sgt = np.zeros((n, SLOTS, 6))
            self.touched = np.zeros(n, dtype=np.int32)
            self.count = 0
            self._n = n

    def begin(self, solver: DFSPHSolver, pi_v: np.ndarray, v: np.ndarray) -> None:
        """Set up one density solve: the slots of the fluid particles next to a body, the
        sources without the bodies' motion, the bodies' acceleration before the solve
        (gravity and the divergence solve's pressures ``pi_v``) and the viscous force of the
        liquid at velocities ``v`` (after its viscosity solve) on them."""
        liquid = self.liquid
        x = liquid.state.positions
        n = x.shape[0]
        self._allocate(n)
        bset = liquid.boundary_set
        owner = self.owner[bset.order]
        sel = np.flatnonzero(owner >= 0)
        start, lo, cell, dims = liquid._stepper.grid
        m = liquid.model
        self.viscous[:] = 0.0
        self.lost[0] = 0
        self.count = _build(sel, np.ascontiguousarray(owner[sel]), bset.sorted_points,
                            bset.sorted_volumes, bset.sorted_normals, self.centers, x, start,
                            lo, cell, dims, m.support, solver.kind, solver.ncl, solver.cn,
                            self.nslot, self.sbody, self.skey, self.sgt, self.touched,
                            self.count, v, bset.sorted_velocities,
                            bset.sorted_friction_volumes, liquid._stepper.nu_b, m.mass,
                            self.viscous, self.lost)
        self.ready = True
        nt = self.count
        touched = np.sort(self.touched[:nt])  # in memory order for the sweeps
        rows = int(self.nslot[touched].sum())
        self.rstart = np.empty(nt + 1, dtype=np.int64)
        self.rbody = np.empty(rows, dtype=np.int32)
        self.rkey = np.empty(rows, dtype=np.int32)
        self.rgt = np.empty((rows, 6))
        self.tsrc = np.empty(nt)
        self.twsrc = np.empty((nt, solver.wsrc.shape[1]))
        _compact(touched, nt, self.nslot, self.sbody, self.skey, self.sgt, solver.src,
                 solver.wsrc, self.rstart, self.rbody, self.rkey, self.rgt, self.tsrc,
                 self.twsrc)
        self.rows_of = touched
        self.solver = solver
        self.mass = m.mass
        self.gravity = np.asarray(liquid.gravity, dtype=np.float64)
        self.base[:] = 0.0
        _wrench(touched, nt, self.rstart, self.rbody, self.rkey, self.rgt, pi_v,
                solver.wall_pressure, solver.ncl, False, m.mass, self.base)

    def wrench(self, pi: np.ndarray, pw: np.ndarray) -> np.ndarray:
        """Force (N) and torque (N m, about the centre of mass) per body, (B, 6), that the
        density solve's pressures ``pi`` and wall pressures ``pw`` and the divergence solve's
        pressures exert on the bodies (the viscous force is not in it)."""
        w = self.base.copy()
        _wrench(self.rows_of, self.count, self.rstart, self.rbody, self.rkey, self.rgt, pi, pw,
                self.solver.ncl, True, self.mass, w)
        return w

    def forces(self) -> np.ndarray | None:
        """Force (N) and torque (N m, about the centre of mass) per body, (B, 6), of the liquid
        in the step just taken: its converged pressures and wall pressures (:meth:`wrench`)
        plus its viscosity, the same sum as :func:`filters.sph.boundary_set.boundary_forces`
        over the bodies' particles without a second pass over the pairs; None where the step
        did not set the link up or a pair was left out of the slots."""
        if not self.ready or self.lost[0]:
            return None
        s = self.solver
        return self.wrench(s.pi, s.wall_pressure) + self.viscous

    def update(self, pi: np.ndarray, pw: np.ndarray, scale: float) -> None:
        """The sources of the next sweep, from the bodies' motion under the pressures ``pi``
        and wall pressures ``pw`` of the last one."""
        s = self.solver
        _update(self.rows_of, self.count, self.rstart, self.rbody, self.rkey, self.rgt, pi, pw,
                s.ncl, self.mass, self.base, self.inv_mass, self.inv_inertia, self.gravity,
                scale, self.tsrc, self.twsrc, s.src, s.wsrc, self.acc)
