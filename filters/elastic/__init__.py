"""Elastic objects: damped springs, their topologies (hair, cloth, jello), contacts, and the
mass-spring simulations that advance them with :mod:`filters.integrators`; finite-element
solids of linear tetrahedra (:mod:`~filters.elastic.materials`, :mod:`~filters.elastic.fem`,
:mod:`~filters.elastic.tetmesh`, :mod:`~filters.elastic.fem_simulation`) advanced the same way.
"""
