"""Elastic objects: damped springs, their topologies (hair, cloth, jello), contacts, and the
mass-spring simulations that advance them with :mod:`filters.integrators`.
"""
