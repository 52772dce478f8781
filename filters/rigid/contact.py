"""Contacts of rigid bodies with the scene's colliders and with each other, and their impulses.

**Detection** (:func:`find_contacts`), at the start of a step: every contact point of a body (its
vertices and edge points, :func:`filters.rigid.body.edge_points`) is tested against

* the colliders of :class:`filters.elastic.contact.Colliders` (planes, spheres and boxes, solid
  or containers; a container box is its six walls, so a point in a corner touches two or three
  of them, each with its own normal), at their ``thickness``;
* the signed distance of every other body whose bounding sphere is near
  (:mod:`filters.rigid.sdf`), both ways round, as Guendelman, Bridson & Fedkiw (2003) do.

A contact is kept while the point is closer than what the bodies can travel in the step (plus a
slop): a *speculative* contact (Catto 2013, "Continuous collision", GDC), which lets the body
close the gap ``phi`` in this step but not cross it: ``v_n >= -phi / h``.

**Impulses** (:func:`solve_velocities`): projected Gauss-Seidel over the contacts with accumulated
impulses (sequential impulses, Catto 2005, "Iterative dynamics with temporal coherence", GDC):
per contact a normal impulse ``lambda_n >= 0`` with ``v_n^+ >= target`` and complementarity, and a
tangential impulse in the contact plane with the Coulomb bound ``|lambda_t| <= mu lambda_n``
(the cone, not a pyramid: a slide in any direction sees the same ``mu``).  The target is 0, or
``-phi / h`` for a gap, or ``-e v_n^-`` (Newton's restitution) for a point that reaches the
surface in this step faster than the threshold speed.  The impulses of the previous step start the
iteration (*warm starting*, matched by body, point and partner), so that a resting stack converges
to its exact impulses and stays at rest.  Sweeps alternate forward and backward.

**Separation** (:func:`solve_positions`): overlaps deeper than the slop are removed by
pseudo-velocities from a second, frictionless solve (the split impulse of Catto's Box2D and
Bullet): they move the bodies in the drift but are not kept, so removing an overlap adds no
kinetic energy and no momentum.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..elastic.threads import serial_below
from .sdf import body_distance, convex_distance

__all__ = ["pack_colliders", "find_contacts", "solve_velocities", "solve_positions",
           "broad_phase", "CONTACT_FIELDS"]

#: Columns of the float contact array: point (3), normal (3), phi, e, mu.
CONTACT_FIELDS = ("px", "py", "pz", "nx", "ny", "nz", "phi", "e", "mu")

#: Below this many contact points the detection runs on one thread (a parallel region costs
#: more than the work, and on a busy machine a descheduled worker stalls it).
PARALLEL_MIN_POINTS = 20_000

_BOX_NORMALS = np.array([[-1.0, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]])


def pack_colliders(colliders):
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
        Solid boxes: lower (3), upper (3), restitution, friction, and 6 planes' offsets are not
        stored: the box kernel rebuilds them.  Layout: lower (3), upper (3), e, mu, 0, 0, 0, 0.
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


def broad_phase(positions, radius, margin, fixed):
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


def find_contacts(points, owner, local, positions, rotations, v, w, fixed, radius, margin,
                  colliders, e_body, mu_body, sdfs, pairs, tie, tie_speed, n_local):
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


# ---------------------------------------------------------------------------------------------
# Projected Gauss-Seidel
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _basis(n0, n1, n2):
    """An orthonormal tangent basis of the plane of ``n`` (Duff et al. 2017, JCGT 6(1))."""
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    return (1.0 + sign * n0 * n0 * a, sign * b, -sign * n0), (b, sign + n1 * n1 * a, -n1)


@njit(cache=True, inline="always")
def _inverse_mass_along(im, ii, rx, ry, rz, dx, dy, dz):
    """``1/m + (r x d) . I^-1 (r x d)`` of one body."""
    cx = ry * dz - rz * dy
    cy = rz * dx - rx * dz
    cz = rx * dy - ry * dx
    return im + (cx * (ii[0, 0] * cx + ii[0, 1] * cy + ii[0, 2] * cz)
                 + cy * (ii[1, 0] * cx + ii[1, 1] * cy + ii[1, 2] * cz)
                 + cz * (ii[2, 0] * cx + ii[2, 1] * cy + ii[2, 2] * cz))


@njit(cache=True, inline="always")
def _apply(v, w, im, ii, b, rx, ry, rz, jx, jy, jz, sign):
    """Apply impulse ``sign * j`` at ``r`` to body ``b``."""
    v[b, 0] += sign * im * jx
    v[b, 1] += sign * im * jy
    v[b, 2] += sign * im * jz
    tx = sign * (ry * jz - rz * jy)
    ty = sign * (rz * jx - rx * jz)
    tz = sign * (rx * jy - ry * jx)
    w[b, 0] += ii[0, 0] * tx + ii[0, 1] * ty + ii[0, 2] * tz
    w[b, 1] += ii[1, 0] * tx + ii[1, 1] * ty + ii[1, 2] * tz
    w[b, 2] += ii[2, 0] * tx + ii[2, 1] * ty + ii[2, 2] * tz


@njit(cache=True, inline="always")
def _relative(v, w, a, b, r, c, dx, dy, dz):
    """``(u_a - u_b) . d`` at contact ``c``, ``u`` the point velocities; ``b < 0`` is static."""
    s = ((v[a, 0] + w[a, 1] * r[c, 2] - w[a, 2] * r[c, 1]) * dx
         + (v[a, 1] + w[a, 2] * r[c, 0] - w[a, 0] * r[c, 2]) * dy
         + (v[a, 2] + w[a, 0] * r[c, 1] - w[a, 1] * r[c, 0]) * dz)
    if b >= 0:
        s -= ((v[b, 0] + w[b, 1] * r[c, 5] - w[b, 2] * r[c, 4]) * dx
              + (v[b, 1] + w[b, 2] * r[c, 3] - w[b, 0] * r[c, 5]) * dy
              + (v[b, 2] + w[b, 0] * r[c, 4] - w[b, 1] * r[c, 3]) * dz)
    return s


@njit(cache=True)
def _arms(ints, floats, positions):
    k = ints.shape[0]
    r = np.zeros((k, 6))
    for c in range(k):
        a = ints[c, 0]
        b = ints[c, 1]
        for d in range(3):
            r[c, d] = floats[c, d] - positions[a, d]
            if b >= 0:
                r[c, 3 + d] = floats[c, d] - positions[b, d]
    return r


@njit(cache=True)
def _mass_along(ints, r, inv_mass, inv_inertia, dx, dy, dz):
    a = ints[0]
    b = ints[1]
    k = _inverse_mass_along(inv_mass[a], inv_inertia[a], r[0], r[1], r[2], dx, dy, dz)
    if b >= 0:
        k += _inverse_mass_along(inv_mass[b], inv_inertia[b], r[3], r[4], r[5], dx, dy, dz)
    return 1.0 / k if k > 0.0 else 0.0


@njit(cache=True)
def solve_velocities(ints, floats, positions, v, w, inv_mass, inv_inertia, warm, threshold, h,
                     iterations, impulses):
    """Contact and friction impulses by projected Gauss-Seidel; ``v``, ``w`` (B, 3) in place.

    Parameters
    ----------
    ints, floats : arrays (K, 3), (K, 9)
        From :func:`find_contacts`.
    positions : (B, 3) float64
        Centres of mass (m).
    v, w : (B, 3) float64
        Velocities and world angular velocities after the forces of the step; updated.
    inv_mass : (B,) float64
        ``1/m`` (0 for fixed bodies).
    inv_inertia : (B, 3, 3) float64
        World inverse inertia tensors (0 for fixed bodies).
    warm : (K, 4) float64
        Starting impulses: normal (N s) and tangential world vector (N s).
    threshold : (B,) float64
        Approach speed (m/s) below which a body's contacts are inelastic.
    h : float
        Step (s).
    iterations : int
        Largest number of sweeps; they stop when no impulse changes by more than 1e-12 of the
        largest.
    impulses : (K, 4) float64
        Out: the impulses, as ``warm``.

    Returns
    -------
    int
        Sweeps done.
    """
    k = ints.shape[0]
    r = _arms(ints, floats, positions)
    tangents = np.empty((k, 6))
    masses = np.empty((k, 3))
    target = np.empty(k)
    lam = np.zeros((k, 3))
    for c in range(k):
        n0, n1, n2 = floats[c, 3], floats[c, 4], floats[c, 5]
        t1, t2 = _basis(n0, n1, n2)
        tangents[c, 0], tangents[c, 1], tangents[c, 2] = t1
        tangents[c, 3], tangents[c, 4], tangents[c, 5] = t2
        masses[c, 0] = _mass_along(ints[c], r[c], inv_mass, inv_inertia, n0, n1, n2)
        masses[c, 1] = _mass_along(ints[c], r[c], inv_mass, inv_inertia, t1[0], t1[1], t1[2])
        masses[c, 2] = _mass_along(ints[c], r[c], inv_mass, inv_inertia, t2[0], t2[1], t2[2])
        a = ints[c, 0]
        b = ints[c, 1]
        phi = floats[c, 6]
        e = floats[c, 7]
        vn = _relative(v, w, a, b, r, c, n0, n1, n2)
        goal = -phi / h if phi > 0.0 else 0.0
        slow = threshold[a] if b < 0 else max(threshold[a], threshold[b])
        if e > 0.0 and vn < -slow and vn * h < -max(phi, 0.0):
            goal = max(goal, -e * vn)
        target[c] = goal
    # warm start
    for c in range(k):
        a = ints[c, 0]
        b = ints[c, 1]
        ln = max(warm[c, 0], 0.0)
        l1 = (warm[c, 1] * tangents[c, 0] + warm[c, 2] * tangents[c, 1]
              + warm[c, 3] * tangents[c, 2])
        l2 = (warm[c, 1] * tangents[c, 3] + warm[c, 2] * tangents[c, 4]
              + warm[c, 3] * tangents[c, 5])
        lt = math.sqrt(l1 * l1 + l2 * l2)
        cap = floats[c, 8] * ln
        if lt > cap:
            l1 *= cap / lt
            l2 *= cap / lt
        lam[c, 0] = ln
        lam[c, 1] = l1
        lam[c, 2] = l2
        jx = ln * floats[c, 3] + l1 * tangents[c, 0] + l2 * tangents[c, 3]
        jy = ln * floats[c, 4] + l1 * tangents[c, 1] + l2 * tangents[c, 4]
        jz = ln * floats[c, 5] + l1 * tangents[c, 2] + l2 * tangents[c, 5]
        _apply(v, w, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1], r[c, 2], jx, jy, jz, 1.0)
        if b >= 0:
            _apply(v, w, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4], r[c, 5], jx, jy, jz,
                   -1.0)
    sweeps = 0
    for it in range(iterations):
        sweeps += 1
        change = 0.0
        largest = 0.0
        for s in range(k):
            c = s if it % 2 == 0 else k - 1 - s
            a = ints[c, 0]
            b = ints[c, 1]
            n0, n1, n2 = floats[c, 3], floats[c, 4], floats[c, 5]
            # normal
            vn = _relative(v, w, a, b, r, c, n0, n1, n2)
            new = max(lam[c, 0] + masses[c, 0] * (target[c] - vn), 0.0)
            dl = new - lam[c, 0]
            lam[c, 0] = new
            if dl != 0.0:
                _apply(v, w, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1], r[c, 2],
                       dl * n0, dl * n1, dl * n2, 1.0)
                if b >= 0:
                    _apply(v, w, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4], r[c, 5],
                           dl * n0, dl * n1, dl * n2, -1.0)
            change = max(change, abs(dl))
            # friction, in the cone |lambda_t| <= mu lambda_n
            cap = floats[c, 8] * lam[c, 0]
            v1 = _relative(v, w, a, b, r, c, tangents[c, 0], tangents[c, 1], tangents[c, 2])
            v2 = _relative(v, w, a, b, r, c, tangents[c, 3], tangents[c, 4], tangents[c, 5])
            l1 = lam[c, 1] - masses[c, 1] * v1
            l2 = lam[c, 2] - masses[c, 2] * v2
            lt = math.sqrt(l1 * l1 + l2 * l2)
            if lt > cap:
                l1 = l1 * cap / lt if lt > 0.0 else 0.0
                l2 = l2 * cap / lt if lt > 0.0 else 0.0
            d1 = l1 - lam[c, 1]
            d2 = l2 - lam[c, 2]
            lam[c, 1] = l1
            lam[c, 2] = l2
            if d1 != 0.0 or d2 != 0.0:
                jx = d1 * tangents[c, 0] + d2 * tangents[c, 3]
                jy = d1 * tangents[c, 1] + d2 * tangents[c, 4]
                jz = d1 * tangents[c, 2] + d2 * tangents[c, 5]
                _apply(v, w, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1], r[c, 2],
                       jx, jy, jz, 1.0)
                if b >= 0:
                    _apply(v, w, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4], r[c, 5],
                           jx, jy, jz, -1.0)
            change = max(change, abs(d1), abs(d2))
            largest = max(largest, lam[c, 0])
        if change <= 1e-12 * largest:
            break
    for c in range(k):
        impulses[c, 0] = lam[c, 0]
        for d in range(3):
            impulses[c, 1 + d] = lam[c, 1] * tangents[c, d] + lam[c, 2] * tangents[c, 3 + d]
    return sweeps


@njit(cache=True)
def solve_positions(ints, floats, positions, inv_mass, inv_inertia, slop, rate, h, iterations,
                    v_push, w_push):
    """Pseudo-velocities ``v_push``, ``w_push`` (B, 3) that remove the fraction ``rate`` of
    every overlap deeper than ``slop`` (m) in a step ``h`` (frictionless projected
    Gauss-Seidel, normal only).  Returns the sweeps done (0 when nothing overlaps)."""
    k = ints.shape[0]
    v_push[:] = 0.0
    w_push[:] = 0.0
    deepest = 0.0
    for c in range(k):
        deepest = max(deepest, -floats[c, 6] - slop)
    if deepest <= 0.0:
        return 0
    r = _arms(ints, floats, positions)
    masses = np.empty(k)
    target = np.empty(k)
    for c in range(k):
        masses[c] = _mass_along(ints[c], r[c], inv_mass, inv_inertia, floats[c, 3],
                                floats[c, 4], floats[c, 5])
        target[c] = rate * max(-floats[c, 6] - slop, 0.0) / h
    lam = np.zeros(k)
    sweeps = 0
    for it in range(iterations):
        sweeps += 1
        change = 0.0
        largest = 0.0
        for s in range(k):
            c = s if it % 2 == 0 else k - 1 - s
            a = ints[c, 0]
            b = ints[c, 1]
            n0, n1, n2 = floats[c, 3], floats[c, 4], floats[c, 5]
            vn = _relative(v_push, w_push, a, b, r, c, n0, n1, n2)
            new = max(lam[c] + masses[c] * (target[c] - vn), 0.0)
            dl = new - lam[c]
            lam[c] = new
            if dl != 0.0:
                _apply(v_push, w_push, inv_mass[a], inv_inertia[a], a, r[c, 0], r[c, 1],
                       r[c, 2], dl * n0, dl * n1, dl * n2, 1.0)
                if b >= 0:
                    _apply(v_push, w_push, inv_mass[b], inv_inertia[b], b, r[c, 3], r[c, 4],
                           r[c, 5], dl * n0, dl * n1, dl * n2, -1.0)
            change = max(change, abs(dl))
            largest = max(largest, lam[c])
        if change <= 1e-12 * largest:
            break
    return sweeps
