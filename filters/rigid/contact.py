"""Contacts of rigid bodies with the scene's colliders and with each other: detection.

:func:`find_contacts`, at the start of a step: every contact point of a body (its
vertices and edge points, :func:`filters.rigid.body.edge_points`) is tested against

* the colliders of :class:`filters.elastic.contact.Colliders` (planes, spheres and boxes, solid
  or containers; a container box is its six walls, so a point in a corner touches two or three
  of them, each with its own normal), at their ``thickness``;
* the signed distance of every other body whose bounding sphere is near
  (:mod:`filters.rigid.sdf`), both ways round, as Guendelman, Bridson & Fedkiw (2003) do.

A contact is kept while the point is closer than what the bodies can travel in the step (plus a
slop): a *speculative* contact (Catto 2013, "Continuous collision", GDC), which lets the body
close the gap ``phi`` in this step but not cross it: ``v_n >= -phi / h``.

Their impulses are solved by :mod:`filters.rigid.impulses`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..elastic.threads import serial_below
from .sdf import body_distance, convex_distance

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from ..elastic.contact import Colliders

__all__ = ["pack_colliders", "find_contacts", "broad_phase", "CONTACT_FIELDS",
           "PARALLEL_MIN_POINTS"]

#: Columns of the float contact array: point (3), normal (3), phi, e, mu.
CONTACT_FIELDS = ("px", "py", "pz", "nx", "ny", "nz", "phi", "e", "mu")

#: Below this many contact points the detection runs on one thread (a parallel region costs
#: more than the work, and on a busy machine a descheduled worker stalls it).
PARALLEL_MIN_POINTS = 20_000

_BOX_NORMALS = np.array([[-1.0, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]])


def pack_colliders(colliders: Colliders | None) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                         NDArray[np.float64], NDArray[np.float64],
                                                         float, NDArray[np.int64]]:
    """The colliders as arrays for :func:`find_contacts`.

    Parameters
    ----------
    colliders : filters.elastic.contact.Colliders or None

    Returns
    -------
    planes : (P, 6) float64
        Unit normal (3), offset (``n . x = d``), restitution, friction; container boxes are
        added as their six walls (normals inwards).
    spheres : (S, 7) float64
        Centre (3), radius, side (+1 solid, -1 container), restitution, friction.
    boxes : (X, 12) float64
        Solid boxes: lower (3), upper (3), restitution, friction, then four unused columns.
    box_planes : (X * 6, 4) float64
        The six face planes of every solid box (normal, offset), for the tie-broken inside
        distance.
    thickness : float
        Distance (m) kept from every collider.
    ids : (P + S + X,) int64
        Index of each packed primitive in ``colliders.shapes`` (a container box's six walls share
        one), for contact keys.
    """
    planes, spheres, boxes, box_planes, ids = [], [], [], [], []
    thickness = 0.0
    if colliders is not None:
        thickness = float(colliders.thickness)
        for row in colliders.planes:
            planes.append(row.copy())
        for row in colliders.spheres:
            spheres.append(row.copy())
        for row in colliders.boxes:
            lo, hi, side, e, mu = row[:3], row[3:6], row[6], row[7], row[8]
            if side < 0.0:  # container: six walls facing inwards
                for k in range(3):
                    planes.append(np.r_[np.eye(3)[k], lo[k], e, mu])
                    planes.append(np.r_[-np.eye(3)[k], -hi[k], e, mu])
            else:
                boxes.append(np.r_[lo, hi, e, mu, 0.0, 0.0, 0.0, 0.0])
                for k in range(6):
                    n = _BOX_NORMALS[k]
                    d = -lo[k // 2] if k % 2 == 0 else hi[k // 2]
                    box_planes.append(np.r_[n, d])
    planes = np.array(planes, dtype=np.float64).reshape(-1, 6)
    spheres = np.array(spheres, dtype=np.float64).reshape(-1, 7)
    boxes = np.array(boxes, dtype=np.float64).reshape(-1, 12)
    box_planes = np.array(box_planes, dtype=np.float64).reshape(-1, 4)
    ids = np.arange(planes.shape[0] + spheres.shape[0] + boxes.shape[0], dtype=np.int64)
    for a in (planes, spheres, boxes, box_planes, ids):
        a.setflags(write=False)
    return planes, spheres, boxes, box_planes, thickness, ids


def broad_phase(positions: np.ndarray, radius: np.ndarray, margin: np.ndarray,
                fixed: np.ndarray) -> NDArray[np.bool_]:
    """Pairs of bodies whose bounding spheres, grown by their margins, overlap: ``(B, B)`` bool,
    symmetric, false on the diagonal and between two fixed bodies."""
    diff = positions[:, None, :] - positions[None, :, :]
    d = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
    reach = radius[:, None] + radius[None, :] + margin[:, None] + margin[None, :]
    pairs = d < reach
    np.fill_diagonal(pairs, False)
    pairs &= ~(fixed[:, None] & fixed[None, :])
    return np.ascontiguousarray(pairs)


@njit(cache=True)
def _box_distance(box, box_planes, c, x, y, z, ux, uy, uz, tie):
    """Signed distance and normal of solid box ``c`` (exact outside, tie-broken inside)."""
    q0 = max(box[0] - x, x - box[3])
    q1 = max(box[1] - y, y - box[4])
    q2 = max(box[2] - z, z - box[5])
    if q0 > 0.0 or q1 > 0.0 or q2 > 0.0:
        o0 = max(q0, 0.0)
        o1 = max(q1, 0.0)
        o2 = max(q2, 0.0)
        d = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
        n0 = o0 / d if x > 0.5 * (box[0] + box[3]) else -o0 / d
        n1 = o1 / d if y > 0.5 * (box[1] + box[4]) else -o1 / d
        n2 = o2 / d if z > 0.5 * (box[2] + box[5]) else -o2 / d
        return d, n0, n1, n2
    return convex_distance(box_planes, 6 * c, 6 * c + 6, x, y, z, ux, uy, uz, tie)


@njit(cache=True)
def _scan_point(i, write, start, cp, owner, local, positions, rotations, v, w, fixed, radius,
                margin, planes, spheres, boxes, box_planes, thickness, e_body, mu_body,
                kinds, plane_start, sdf_planes, grid_meta, grid_values, pairs, tie, tie_speed,
                n_local, n_partners, out_i, out_f):
    """Count (``write`` False) or write from row ``start`` the contacts of contact point ``i``."""
    a = owner[i]
    ra = rotations[a]
    X = cp[i]
    rx = ra[0, 0] * X[0] + ra[0, 1] * X[1] + ra[0, 2] * X[2]
    ry = ra[1, 0] * X[0] + ra[1, 1] * X[1] + ra[1, 2] * X[2]
    rz = ra[2, 0] * X[0] + ra[2, 1] * X[1] + ra[2, 2] * X[2]
    px = positions[a, 0] + rx
    py = positions[a, 1] + ry
    pz = positions[a, 2] + rz
    # the point's velocity
    ux = v[a, 0] + w[a, 1] * rz - w[a, 2] * ry
    uy = v[a, 1] + w[a, 2] * rx - w[a, 0] * rz
    uz = v[a, 2] + w[a, 0] * ry - w[a, 1] * rx
    n_bodies = positions.shape[0]
    count = 0
    base_key = (a * n_local + local[i]) * n_partners
    if not fixed[a]:
        c = 0
        for j in range(planes.shape[0]):
            phi = (planes[j, 0] * px + planes[j, 1] * py + planes[j, 2] * pz - planes[j, 3]
                   - thickness)
            if phi < margin[a]:
                if write:
                    r = start + count
                    out_i[r, 0] = a
                    out_i[r, 1] = -1
                    out_i[r, 2] = base_key + n_bodies + c
                    out_f[r, 0], out_f[r, 1], out_f[r, 2] = px, py, pz
                    out_f[r, 3], out_f[r, 4], out_f[r, 5] = planes[j, 0], planes[j, 1], planes[j, 2]
                    out_f[r, 6] = phi
                    out_f[r, 7] = max(planes[j, 4], e_body[a])
                    out_f[r, 8] = math.sqrt(planes[j, 5] * mu_body[a])
                count += 1
            c += 1
        for j in range(spheres.shape[0]):
            dx = px - spheres[j, 0]
            dy = py - spheres[j, 1]
            dz = pz - spheres[j, 2]
            dist = math.sqrt(dx * dx + dy * dy + dz * dz)
            side = spheres[j, 4]
            phi = side * (dist - spheres[j, 3]) - thickness
            if phi < margin[a]:
                if write:
                    if dist > 0.0:
                        n0, n1, n2 = side * dx / dist, side * dy / dist, side * dz / dist
                    else:
                        n0, n1, n2 = 0.0, 0.0, 1.0
                    r = start + count
                    out_i[r, 0] = a
                    out_i[r, 1] = -1
                    out_i[r, 2] = base_key + n_bodies + c
                    out_f[r, 0], out_f[r, 1], out_f[r, 2] = px, py, pz
                    out_f[r, 3], out_f[r, 4], out_f[r, 5] = n0, n1, n2
                    out_f[r, 6] = phi
                    out_f[r, 7] = max(spheres[j, 5], e_body[a])
                    out_f[r, 8] = math.sqrt(spheres[j, 6] * mu_body[a])
                count += 1
            c += 1
        for j in range(boxes.shape[0]):
            # at an edge, the face the point moves into; at rest, the one facing the body
            ex = positions[a, 0] - 0.5 * (boxes[j, 0] + boxes[j, 3])
            ey = positions[a, 1] - 0.5 * (boxes[j, 1] + boxes[j, 4])
            ez = positions[a, 2] - 0.5 * (boxes[j, 2] + boxes[j, 5])
            el = tie_speed / max(math.sqrt(ex * ex + ey * ey + ez * ez), 1e-300)
            d, n0, n1, n2 = _box_distance(boxes[j], box_planes, j, px, py, pz, ux - el * ex,
                                          uy - el * ey, uz - el * ez, tie)
            phi = d - thickness
            if phi < margin[a]:
                if write:
                    r = start + count
                    out_i[r, 0] = a
                    out_i[r, 1] = -1
                    out_i[r, 2] = base_key + n_bodies + c
                    out_f[r, 0], out_f[r, 1], out_f[r, 2] = px, py, pz
                    out_f[r, 3], out_f[r, 4], out_f[r, 5] = n0, n1, n2
                    out_f[r, 6] = phi
                    out_f[r, 7] = max(boxes[j, 6], e_body[a])
                    out_f[r, 8] = math.sqrt(boxes[j, 7] * mu_body[a])
                count += 1
            c += 1
    for b in range(n_bodies):
        if not pairs[a, b]:
            continue
        dx = px - positions[b, 0]
        dy = py - positions[b, 1]
        dz = pz - positions[b, 2]
        reach = radius[b] + margin[a] + margin[b]
        if dx * dx + dy * dy + dz * dz >= reach * reach:
            continue
        rb = rotations[b]
        # the point and its velocity relative to b, in b's frame
        gx = ux - (v[b, 0] + w[b, 1] * dz - w[b, 2] * dy)
        gy = uy - (v[b, 1] + w[b, 2] * dx - w[b, 0] * dz)
        gz = uz - (v[b, 2] + w[b, 0] * dy - w[b, 1] * dx)
        xb = rb[0, 0] * dx + rb[1, 0] * dy + rb[2, 0] * dz
        yb = rb[0, 1] * dx + rb[1, 1] * dy + rb[2, 1] * dz
        zb = rb[0, 2] * dx + rb[1, 2] * dy + rb[2, 2] * dz
        # tie-break: the relative velocity, then the direction from b's centre to a's
        ex = positions[a, 0] - positions[b, 0]
        ey = positions[a, 1] - positions[b, 1]
        ez = positions[a, 2] - positions[b, 2]
        el = tie_speed / max(math.sqrt(ex * ex + ey * ey + ez * ez), 1e-300)
        gx -= el * ex
        gy -= el * ey
        gz -= el * ez
        ubx = rb[0, 0] * gx + rb[1, 0] * gy + rb[2, 0] * gz
        uby = rb[0, 1] * gx + rb[1, 1] * gy + rb[2, 1] * gz
        ubz = rb[0, 2] * gx + rb[1, 2] * gy + rb[2, 2] * gz
        phi, m0, m1, m2 = body_distance(kinds, plane_start, sdf_planes, grid_meta, grid_values,
                                        b, xb, yb, zb, ubx, uby, ubz, tie)
        if phi < margin[a] + margin[b]:
            if write:
                r = start + count
                out_i[r, 0] = a
                out_i[r, 1] = b
                out_i[r, 2] = base_key + b
                out_f[r, 0], out_f[r, 1], out_f[r, 2] = px, py, pz
                out_f[r, 3] = rb[0, 0] * m0 + rb[0, 1] * m1 + rb[0, 2] * m2
                out_f[r, 4] = rb[1, 0] * m0 + rb[1, 1] * m1 + rb[1, 2] * m2
                out_f[r, 5] = rb[2, 0] * m0 + rb[2, 1] * m1 + rb[2, 2] * m2
                out_f[r, 6] = phi
                out_f[r, 7] = max(e_body[a], e_body[b])
                out_f[r, 8] = math.sqrt(mu_body[a] * mu_body[b])
            count += 1
    return count


@njit(parallel=True, cache=True)
def _count(cp, owner, local, positions, rotations, v, w, fixed, radius, margin, planes, spheres,
           boxes, box_planes, thickness, e_body, mu_body, kinds, plane_start, sdf_planes,
           grid_meta, grid_values, pairs, tie, tie_speed, n_local, n_partners, counts):
    dummy_i = np.zeros((0, 3), dtype=np.int64)
    dummy_f = np.zeros((0, 9))
    for i in prange(cp.shape[0]):
        counts[i] = _scan_point(i, False, 0, cp, owner, local, positions, rotations, v, w, fixed,
                                radius, margin, planes, spheres, boxes, box_planes, thickness,
                                e_body, mu_body, kinds, plane_start, sdf_planes, grid_meta,
                                grid_values, pairs, tie, tie_speed, n_local, n_partners, dummy_i,
                                dummy_f)


@njit(parallel=True, cache=True)
def _fill(cp, owner, local, positions, rotations, v, w, fixed, radius, margin, planes, spheres,
          boxes, box_planes, thickness, e_body, mu_body, kinds, plane_start, sdf_planes,
          grid_meta, grid_values, pairs, tie, tie_speed, n_local, n_partners, starts, out_i,
          out_f):
    for i in prange(cp.shape[0]):
        if starts[i + 1] > starts[i]:
            _scan_point(i, True, starts[i], cp, owner, local, positions, rotations, v, w, fixed,
                        radius, margin, planes, spheres, boxes, box_planes, thickness, e_body,
                        mu_body, kinds, plane_start, sdf_planes, grid_meta, grid_values, pairs,
                        tie, tie_speed, n_local, n_partners, out_i, out_f)


def find_contacts(points: np.ndarray, owner: np.ndarray, local: np.ndarray, positions: np.ndarray,
                  rotations: np.ndarray, v: np.ndarray, w: np.ndarray, fixed: np.ndarray,
                  radius: np.ndarray, margin: np.ndarray, colliders: tuple, e_body: np.ndarray,
                  mu_body: np.ndarray, sdfs: tuple, pairs: np.ndarray, tie: float, tie_speed: float,
                  n_local: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """All contacts of the bodies' contact points at the current positions.

    Parameters
    ----------
    points : (P, 3) float64
        Body-frame contact points of all bodies, concatenated (m).
    owner, local : (P,) int64
        Body of each point, and its index among that body's points.
    positions, rotations, v, w : arrays (B, 3), (B, 3, 3), (B, 3), (B, 3)
        Centres of mass (m), orientations, velocities (m/s) and angular velocities (rad/s, world)
        after the forces of the step.
    fixed : (B,) bool
    radius, margin : (B,) float64
        Bounding radii (m) and the contact margins (m): how far a body can travel in the step
        plus the slop.
    colliders : tuple
        :func:`pack_colliders` of the scene's colliders.
    e_body, mu_body : (B,) float64
        Restitution and friction of the bodies (mixed with the partner's: ``max(e)``,
        ``sqrt(mu mu')``).
    sdfs : tuple
        :func:`filters.rigid.sdf.pack_sdfs` of the bodies.
    pairs : (B, B) bool
        :func:`broad_phase`.
    tie : float
        Tie tolerance (m) of convex distances (the faces within it of the largest distance).
    tie_speed : float
        Speed (m/s) that weighs the direction between the bodies' centres against their
        relative velocity in choosing among tied faces: the face the point moves into fastest
        wins while it moves much faster than this; at rest, the face that looks towards the
        point's body (a box stacked on another touches the top face, not a side).
    n_local : int
        The largest number of contact points of a body (for the keys).

    Returns
    -------
    ints : (K, 3) int64
        Body ``a`` (pushed along ``+n``), partner body ``b`` (-1 for a collider) and a key that
        identifies the contact (body, point, partner) from step to step.
    floats : (K, 9) float64
        Columns :data:`CONTACT_FIELDS`: the world point (m), the unit normal out of the
        partner, the signed distance (m), restitution and friction.
    """
    planes, spheres, boxes, box_planes, thickness, ids = colliders
    n_partners = positions.shape[0] + ids.shape[0]
    args = (points, owner, local, positions, rotations, v, w, fixed, radius, margin, planes,
            spheres, boxes, box_planes, thickness, e_body, mu_body, *sdfs, pairs, tie, tie_speed,
            n_local, n_partners)
    counts = np.zeros(points.shape[0], dtype=np.int64)
    with serial_below(points.shape[0], PARALLEL_MIN_POINTS):
        _count(*args, counts)
        starts = np.zeros(points.shape[0] + 1, dtype=np.int64)
        np.cumsum(counts, out=starts[1:])
        k = int(starts[-1])
        out_i = np.empty((k, 3), dtype=np.int64)
        out_f = np.empty((k, 9))
        if k:
            _fill(*args, starts, out_i, out_f)
    return out_i, out_f
