"""Composable velocity and force fields (see :mod:`filters.fields.terms`), packed for Numba
kernels (:mod:`filters.fields.packed`)."""

from . import terms
from .packed import PackedField, evaluate_packed, field_point, field_point_jacobian, jacobian_packed
from .terms import (  # noqa: F401
                    CurlNoise,
                    Drag,
                    Field,
                    FieldSum,
                    Gravity,
                    NoiseWind,
                    RigidRotation,
                    Uniform,
                    Vortex,
)

__all__ = [*terms.__all__, "PackedField", "field_point", "field_point_jacobian",
           "evaluate_packed", "jacobian_packed"]
