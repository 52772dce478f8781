"""Meshes shared by the rigid-body tests."""

import math

import numpy as np

from filters.elastic.topology import icosphere
from filters.rigid import quaternion_from_axis_angle, rotation_matrices
from filters.rigid.meshes import box_mesh

__all__ = ["box_mesh", "ball", "tetrahedron", "l_prism", "tet_inertia"]


def ball(radius, subdivisions=3, center=(0.0, 0.0, 0.0)):
    """An icosphere turned so that one vertex is its lowest point, straight below the centre."""
    v, f = icosphere(radius, subdivisions)
    top = v[4] / np.linalg.norm(v[4])
    down = np.array([0.0, 0.0, -1.0])
    r = rotation_matrices([quaternion_from_axis_angle(np.cross(top, down),
                                                      math.acos(top @ down))])[0]
    return v @ r.T + np.asarray(center, dtype=float), f


def tetrahedron(points):
    """A tetrahedron of four points (outward faces whatever their order)."""
    p = np.asarray(points, dtype=float)
    faces = np.array([(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
    if np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p[3] - p[0]) < 0:
        faces = faces[:, [0, 2, 1]]
    return p, faces


def tet_inertia(points, density):
    """Mass, centre and inertia about the centre of a tetrahedron by the closed-form second
    moment ``integral x x^T dV = V / 20 (sum p_i p_i^T + (sum p_i)(sum p_i)^T)``."""
    p = np.asarray(points, dtype=float)
    volume = abs(np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p[3] - p[0])) / 6.0
    second = volume / 20.0 * (p.T @ p + np.outer(p.sum(0), p.sum(0)))
    center = p.mean(axis=0)
    second -= volume * np.outer(center, center)
    inertia = density * (np.trace(second) * np.eye(3) - second)
    return density * volume, center, inertia


def l_prism(width=0.2):
    """An L-shaped prism (non-convex): the L (0,0)-(0.3,0)-(0.3,0.1)-(0.1,0.1)-(0.1,0.3)-(0,0.3)
    in the x-z plane, extruded over y in [-width/2, width/2]; volume 0.05 width."""
    outline = [(0, 0), (0.3, 0), (0.3, 0.1), (0.1, 0.1), (0.1, 0.3), (0, 0.3)]
    n = len(outline)
    h = width / 2
    verts = np.array([[x, h, z] for x, z in outline] + [[x, -h, z] for x, z in outline])
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i)]
    for a, b, c in [(0, 1, 2), (0, 2, 3), (0, 3, 5), (3, 4, 5)]:
        faces += [(a, c, b), (n + a, n + b, n + c)]
    faces = np.array(faces)
    # orient outwards
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    if np.einsum("ij,ij->", a, np.cross(b, c)) < 0:
        faces = faces[:, [0, 2, 1]]
    return verts, faces
