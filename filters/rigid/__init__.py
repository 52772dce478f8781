"""Rigid bodies: closed triangle meshes with exact mass properties, moved by forces and contacts.

:class:`RigidBody` (:mod:`~filters.rigid.body`) is one body's fixed data -- mesh, density, mass,
centre of mass and inertia (:mod:`~filters.rigid.mass`), contact points, distance function
(:mod:`~filters.rigid.sdf`), surface samples for a liquid coupling; :class:`RigidBodies`
(:mod:`~filters.rigid.simulation`) advances several of them with the project's simulation
protocol: symplectic Euler with an exact torque-free rotation (:mod:`~filters.rigid.dynamics`),
contacts with the colliders and between bodies with Coulomb friction and restitution
(:mod:`~filters.rigid.contact`).  Orientations are unit quaternions
(:mod:`~filters.rigid.quaternion`).
"""

from .body import RigidBody, edge_points
from .mass import MassProperties, check_closed_mesh, mass_properties
from .quaternion import quaternion_from_axis_angle, rotation_matrices
from .simulation import RigidBodies, RigidModel

__all__ = ["RigidBody", "RigidBodies", "RigidModel", "MassProperties", "check_closed_mesh",
           "mass_properties", "edge_points", "quaternion_from_axis_angle", "rotation_matrices"]
