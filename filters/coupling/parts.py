"""The bodies of a :class:`filters.coupling.Coupled` liquid: how each kind is sampled, moved and
pushed.

A *part* wraps one body simulation and answers, for the liquid, where its boundary particles
are, how fast they move and which way their surface faces, and takes back the forces the
liquid exerted on them:

* :class:`RigidPart` (:class:`filters.rigid.RigidBodies`): the solid layers of every body
  (:func:`filters.coupling.samples.solid_layers`) in its body frame, moved rigidly (``x + R X``,
  ``v + w x R X``, normals ``R N``); the forces summed into a force and a torque per body
  (:meth:`filters.rigid.RigidBodies.apply_point_forces`).
* :class:`ElasticPart` (:class:`filters.elastic.fem_simulation.FEMSimulation`): the solid
  layers of its embedded surface at rest, carried by the tetrahedra with barycentric weights
  (``x = sum w_k x_k``, the same for velocities, normals by the inverse transpose of the
  tetrahedron's deformation gradient); each force split over the tetrahedron's four nodes
  with the same weights (the consistent nodal load, which does the same virtual work), held
  constant through the solid's implicit step (:attr:`filters.elastic.fem.FEMSystem.loads`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike

from ..elastic.fem_simulation import FEMSimulation
from ..rigid import RigidBodies
from ..rigid.quaternion import rotation_matrices
from ..rigid.sdf import body_distance, pack_sdfs, triangle_distance, winding_number
from ..simulation import State
from .samples import locate_in_tets, solid_layers

__all__ = ["RigidPart", "ElasticPart", "make_part", "count_inside", "inside_depths",
           "world_meshes"]


@njit(parallel=True, cache=True)
def _depths(points, v, f, lo, hi, out):
    for i in prange(points.shape[0]):
        out[i] = 0.0
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]:
            if winding_number(x, y, z, v, f) > 0.5:
                best = np.inf
                for t in range(f.shape[0]):
                    best = min(best, triangle_distance(x, y, z, v, f, t))
                out[i] = math.sqrt(best)


def inside_depths(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike) -> np.ndarray:
    """How deep (m) each of ``points`` (N, 3) lies inside the closed mesh ``(vertices,
    faces)``: its distance to the surface where the generalised winding number (Jacobson et
    al. 2013) is above 1/2, else 0; (N,)."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    out = np.zeros(p.shape[0])
    if p.shape[0]:
        _depths(p, v, np.ascontiguousarray(faces, dtype=np.int64), v.min(axis=0),
                v.max(axis=0), out)
    return out


def count_inside(points: ArrayLike, vertices: ArrayLike, faces: ArrayLike) -> np.ndarray:
    """Which ``points`` (N, 3) lie inside the closed mesh ``(vertices, faces)``; (N,) bool."""
    return inside_depths(points, vertices, faces) > 0.0


@njit(cache=True)
def _push_out(x, v, mass, packed, centers, rot, vel, ang, radius, gap, impulse):
    kinds, plane_start, planes, grid_meta, grid_values = packed
    count = 0
    for i in range(x.shape[0]):
        for b in range(centers.shape[0]):
            dx = x[i, 0] - centers[b, 0]
            dy = x[i, 1] - centers[b, 1]
            dz = x[i, 2] - centers[b, 2]
            if dx * dx + dy * dy + dz * dz > radius[b] * radius[b]:
                continue
            r = rot[b]
            lx = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz  # R^T (x - c)
            ly = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
            lz = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
            d, n0, n1, n2 = body_distance(kinds, plane_start, planes, grid_meta, grid_values, b,
                                          lx, ly, lz, 0.0, 0.0, 0.0, 0.0)
            if d >= 0.0:
                continue
            nx = r[0, 0] * n0 + r[0, 1] * n1 + r[0, 2] * n2
            ny = r[1, 0] * n0 + r[1, 1] * n1 + r[1, 2] * n2
            nz = r[2, 0] * n0 + r[2, 1] * n1 + r[2, 2] * n2
            step = gap - d
            x[i, 0] += step * nx
            x[i, 1] += step * ny
            x[i, 2] += step * nz
            # the body's velocity at the particle; remove the particle's approach along n
            px = x[i, 0] - centers[b, 0]
            py = x[i, 1] - centers[b, 1]
            pz = x[i, 2] - centers[b, 2]
            ux = v[i, 0] - (vel[b, 0] + ang[b, 1] * pz - ang[b, 2] * py)
            uy = v[i, 1] - (vel[b, 1] + ang[b, 2] * px - ang[b, 0] * pz)
            uz = v[i, 2] - (vel[b, 2] + ang[b, 0] * py - ang[b, 1] * px)
            un = ux * nx + uy * ny + uz * nz
            if un < 0.0:
                jx, jy, jz = -mass * un * nx, -mass * un * ny, -mass * un * nz
                v[i, 0] += jx / mass
                v[i, 1] += jy / mass
                v[i, 2] += jz / mass
                impulse[b, 0] -= jx  # the body takes the opposite impulse
                impulse[b, 1] -= jy
                impulse[b, 2] -= jz
                impulse[b, 3] -= py * jz - pz * jy
                impulse[b, 4] -= pz * jx - px * jz
                impulse[b, 5] -= px * jy - py * jx
            count += 1
    return count


class RigidPart:
    """The rigid bodies of a :class:`filters.rigid.RigidBodies` in a liquid.

    Parameters
    ----------
    sim : RigidBodies
    spacing : float
        The liquid's particle spacing (m).
    support_factor : float
        Its kernel support over the spacing.
    kernel : str
        Its kernel.
    """

    kind = "rigid"

    def __init__(self, sim: RigidBodies, spacing: float, support_factor: float, kernel: str):
        self.sim = sim
        local, owner, normals = [], [], []
        for b, body in enumerate(sim.model.bodies):
            # the lattice starts at the mesh's corner as given, so that a box given on the
            # fluid's lattice is sampled on it
            layer = solid_layers(body.vertices, body.faces, spacing,
                                 support_factor=support_factor, kernel=kernel)
            local.append(layer.points)
            normals.append(layer.normals)
            owner.append(np.full(layer.n_points, b, dtype=np.int64))
            self.volume = float(layer.volumes[0])
        self.local = np.ascontiguousarray(np.concatenate(local))
        self.local_normals = np.ascontiguousarray(np.concatenate(normals))
        self.owner = np.concatenate(owner)
        self.n_samples = self.local.shape[0]
        self._packed = pack_sdfs([body.sdf for body in sim.model.bodies])

    def boundary(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World positions (m), velocities (m/s) and unit normals of the samples, (S, 3) each."""
        x, v = self.sim.to_world(self.local, self.owner)
        rot = rotation_matrices(self.sim.state.extra["orientations"])
        n = np.einsum("sij,sj->si", rot[self.owner], self.local_normals)
        n /= np.sqrt((n * n).sum(axis=1))[:, None]
        return x, v, n

    def volumes(self) -> np.ndarray:
        """SPH volumes (m^3) of the samples (S,)."""
        return np.full(self.n_samples, self.volume)

    def push_out(self, x: np.ndarray, v: np.ndarray, mass: float, gap: float) -> int:
        """Put liquid particles found inside a body back ``gap`` (m) outside its surface, along
        the surface normal, and take away their velocity into it relative to the body; the
        body takes the opposite impulse (momentum is kept).  ``x`` and ``v`` (N, 3) of
        particles of ``mass`` (kg) change in place.  Returns how many particles were moved.

        The safety net of the bodies, as ``container`` is the tank's: the DFSPH wall
        constraints hold the liquid off a body's faces, but at its convex corners the body
        fills too little of a particle's kernel for them to act.
        """
        sim = self.sim
        s = sim.state
        rot = rotation_matrices(s.extra["orientations"])
        bodies = sim.model.bodies
        radius = np.array([b.radius for b in bodies]) + gap
        impulse = np.zeros((len(bodies), 6))
        w = s.extra["angular_velocities"]
        count = _push_out(x, v, float(mass), self._packed, s.positions, rot, s.velocities, w,
                          radius, float(gap), impulse)
        if count:
            for b, body in enumerate(bodies):
                if body.fixed or not impulse[b].any():
                    continue
                s.velocities[b] += impulse[b, :3] / body.mass
                inv = rot[b] @ np.linalg.inv(body.inertia) @ rot[b].T
                w[b] += inv @ impulse[b, 3:]
        return count

    def dynamics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per body: centre of mass (B, 3) (m), inverse mass (B,) (1/kg; 0 for a fixed body)
        and world inverse inertia tensor (B, 3, 3) (1/(kg m^2); 0 for a fixed body)."""
        inv_mass, inv_inertia = self.sim.inverse_masses()
        return np.array(self.sim.state.positions, dtype=np.float64), inv_mass, inv_inertia

    def push(self, points: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """Apply the liquid's ``forces`` (S, 3) (N) at the samples' ``points`` (S, 3) for the next
        step; returns the force and torque per body, (B, 6)."""
        return self.sim.apply_point_forces(points, forces, self.owner)

    def push_wrenches(self, wrenches: np.ndarray) -> np.ndarray:
        """Apply the liquid's force and torque per body, (B, 6), for the next step; returns
        them."""
        self.sim.apply_wrenches(wrenches)
        return wrenches

    def step(self, dt: float) -> None:
        """Advance the bodies by ``dt`` (s)."""
        self.sim.step(dt)

    def meshes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """World vertices (V, 3) and triangles of every body, as a list of pairs."""
        return world_meshes(self.sim)

    def field_data(self) -> dict:
        """Per body: ``body_position`` (centre of mass, m), ``body_orientation`` (w, x, y, z),
        ``body_translation`` (``x = R X + t`` maps the mesh as given, m)."""
        s = self.sim.state
        q = s.extra["orientations"]
        rot = rotation_matrices(q)
        center = np.array([b.center for b in self.sim.model.bodies])
        return {"body_position": s.positions.copy(), "body_orientation": q.copy(),
                "body_translation": s.positions - np.einsum("bij,bj->bi", rot, center)}

    def momentum(self) -> np.ndarray:
        """Linear momentum (kg m/s) of the moving bodies, (3,)."""
        return self.sim.momentum()[0]


@njit(cache=True)
def _embedded(x, v, nodes, w, dm_inv, n0, out_x, out_v, out_n):
    for s in range(nodes.shape[0]):
        a, b, c, d = nodes[s, 0], nodes[s, 1], nodes[s, 2], nodes[s, 3]
        for k in range(3):
            out_x[s, k] = (w[s, 0] * x[a, k] + w[s, 1] * x[b, k] + w[s, 2] * x[c, k]
                           + w[s, 3] * x[d, k])
            out_v[s, k] = (w[s, 0] * v[a, k] + w[s, 1] * v[b, k] + w[s, 2] * v[c, k]
                           + w[s, 3] * v[d, k])
        # deformation gradient F = Ds Dm^-1; the normal follows F^-T n0 = cof(F) n0 / det F
        f00 = f01 = f02 = f10 = f11 = f12 = f20 = f21 = f22 = 0.0
        for m in range(3):
            e0 = x[b, m] - x[a, m]
            e1 = x[c, m] - x[a, m]
            e2 = x[d, m] - x[a, m]
            r0 = e0 * dm_inv[s, 0, 0] + e1 * dm_inv[s, 1, 0] + e2 * dm_inv[s, 2, 0]
            r1 = e0 * dm_inv[s, 0, 1] + e1 * dm_inv[s, 1, 1] + e2 * dm_inv[s, 2, 1]
            r2 = e0 * dm_inv[s, 0, 2] + e1 * dm_inv[s, 1, 2] + e2 * dm_inv[s, 2, 2]
            if m == 0:
                f00, f01, f02 = r0, r1, r2
            elif m == 1:
                f10, f11, f12 = r0, r1, r2
            else:
                f20, f21, f22 = r0, r1, r2
        p0, p1, p2 = n0[s, 0], n0[s, 1], n0[s, 2]
        nx = ((f11 * f22 - f12 * f21) * p0 + (f12 * f20 - f10 * f22) * p1
              + (f10 * f21 - f11 * f20) * p2)
        ny = ((f02 * f21 - f01 * f22) * p0 + (f00 * f22 - f02 * f20) * p1
              + (f01 * f20 - f00 * f21) * p2)
        nz = ((f01 * f12 - f02 * f11) * p0 + (f02 * f10 - f00 * f12) * p1
              + (f00 * f11 - f01 * f10) * p2)
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            out_n[s, 0] = nx / length
            out_n[s, 1] = ny / length
            out_n[s, 2] = nz / length
        else:
            out_n[s, 0] = 0.0
            out_n[s, 1] = 0.0
            out_n[s, 2] = 0.0


class ElasticPart:
    """A finite-element solid (:class:`filters.elastic.fem_simulation.FEMSimulation` with an
    embedded surface) in a liquid; parameters as :class:`RigidPart`."""

    kind = "elastic"

    def __init__(self, sim: FEMSimulation, spacing: float, support_factor: float, kernel: str):
        emb = sim.model.mesh.embedding
        if emb is None or emb.triangles.shape[0] < 4:
            raise ValueError("an elastic body in a liquid needs its embedded surface "
                             "(FEMSimulation.from_mesh or from_tets)")
        self.sim = sim
        rest = sim.model.mesh.positions
        tets = sim.model.mesh.tets
        layer = solid_layers(emb.rest_points, emb.triangles, spacing,
                             support_factor=support_factor, kernel=kernel)
        tet, self.weights = locate_in_tets(layer.points, rest, tets)
        self.nodes = np.ascontiguousarray(tets[tet])
        dm = np.transpose(rest[self.nodes[:, 1:]] - rest[self.nodes[:, :1]], (0, 2, 1))
        self.dm_inv = np.ascontiguousarray(np.linalg.inv(dm))
        self.rest_normals = np.ascontiguousarray(layer.normals)
        self.volume = float(layer.volumes[0])
        self.n_samples = layer.n_points
        self.triangles = emb.triangles

    def boundary(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World positions (m), velocities (m/s) and unit normals of the samples, (S, 3) each."""
        s = self.sim.state
        out = [np.empty((self.n_samples, 3)) for _ in range(3)]
        _embedded(s.positions, s.velocities, self.nodes, self.weights, self.dm_inv,
                  self.rest_normals, *out)
        return tuple(out)

    def volumes(self) -> np.ndarray:
        """SPH volumes (m^3) of the samples (S,)."""
        return np.full(self.n_samples, self.volume)

    def push_out(self, x: np.ndarray, v: np.ndarray, mass: float, gap: float) -> int:
        """No safety net for a deforming body (its surface has no distance function): 0."""
        return 0

    def push(self, points: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """Spread the liquid's ``forces`` (S, 3) (N) over the nodes for the next step; returns
        the total force (N) and torque (N m) about the solid's centre of mass, (1, 6)."""
        n = self.sim.state.n_points
        loads = np.zeros((n, 3))
        for k in range(3):  # three bincounts over (S * 4) entries, no loop over samples
            loads[:, k] = np.bincount(self.nodes.ravel(), (self.weights * forces[:, k:k + 1]
                                                           ).ravel(), minlength=n)
        self.sim.system.loads = loads
        m = self.sim.system.masses
        center = (m[:, None] * self.sim.state.positions).sum(axis=0) / m.sum()
        total = forces.sum(axis=0)
        torque = np.cross(points - center, forces).sum(axis=0)
        return np.concatenate([total, torque])[None, :]

    def step(self, dt: float) -> None:
        """Advance the solid by ``dt`` (s) under the loads of :meth:`push`, then drop them."""
        try:
            self.sim.step(dt)
        finally:
            self.sim.system.loads = None

    def meshes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The embedded surface where it is now: [(vertices (M, 3), triangles)]."""
        return world_meshes(self.sim)

    def field_data(self) -> dict:
        """``solid_surface``: the embedded surface's vertices (M, 3) (m)."""
        return {"solid_surface": self.sim.mesh_points()}

    def momentum(self) -> np.ndarray:
        """Linear momentum (kg m/s), (3,)."""
        return (self.sim.system.masses[:, None] * self.sim.state.velocities).sum(axis=0)


def world_meshes(sim: RigidBodies | FEMSimulation) -> list[tuple[np.ndarray, np.ndarray]]:
    """The surfaces of a body simulation where they are now: a list of ``(vertices (V, 3),
    triangles (T, 3))`` (a rigid body's mesh moved to its pose; a solid's embedded surface)."""
    if isinstance(sim, RigidBodies):
        rot = rotation_matrices(sim.state.extra["orientations"])
        x = sim.state.positions
        return [(np.asarray(body.vertices) @ rot[b].T + x[b], np.asarray(body.faces))
                for b, body in enumerate(sim.model.bodies)]
    if isinstance(sim, FEMSimulation):
        return [(sim.mesh_points(), sim.model.mesh.embedding.triangles)]
    raise TypeError(f"bodies must be RigidBodies or FEMSimulation objects, got "
                    f"{type(sim).__name__}")


def make_part(sim: RigidBodies | FEMSimulation, spacing: float, support_factor: float,
              kernel: str) -> RigidPart | ElasticPart:
    """The part for a body simulation: :class:`RigidPart` or :class:`ElasticPart`."""
    if isinstance(sim, RigidBodies):
        return RigidPart(sim, spacing, support_factor, kernel)
    if isinstance(sim, FEMSimulation):
        return ElasticPart(sim, spacing, support_factor, kernel)
    raise TypeError(f"bodies must be RigidBodies or FEMSimulation objects, got "
                    f"{type(sim).__name__}")


def split_state(state: State, prefix: str) -> State:
    """The sub-state stored under ``prefix`` in a coupled state's extras."""
    e = state.extra
    extra = {k[len(prefix) + 1:]: v for k, v in e.items()
             if k.startswith(prefix + ":") and k.count(":") >= 1
             and k[len(prefix) + 1:] not in ("positions", "velocities", "step")}
    return State(np.asarray(e[prefix + ":positions"]).reshape(-1, 3),
                 np.asarray(e[prefix + ":velocities"]).reshape(-1, 3), state.time,
                 int(np.asarray(e[prefix + ":step"]).ravel()[0]), extra)


def merge_state(extra: dict, prefix: str, state: State) -> None:
    """Store ``state`` (positions, velocities, step and extras) in ``extra`` under ``prefix``."""
    extra[prefix + ":positions"] = state.positions
    extra[prefix + ":velocities"] = state.velocities
    extra[prefix + ":step"] = np.array([state.step], dtype=np.int64)
    for k, v in state.extra.items():
        extra[f"{prefix}:{k}"] = v
