"""The names of the schemes (:data:`SCHEMES`), their check, and :func:`integrate`."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .explicit import euler, symplectic_euler
from .linearized import linearized_backward_euler
from .newton import backward_euler

if TYPE_CHECKING:
    from collections.abc import Sequence
    from typing import Any

    from ..linalg.protocol import ImplicitSystem
    from ..simulation import State
    from .common import StepInfo

__all__ = ["SCHEMES", "check_scheme", "integrate"]

SCHEMES = {
    "euler": euler,
    "symplectic_euler": symplectic_euler,
    "linearized_backward_euler": linearized_backward_euler,
    "backward_euler": backward_euler,
}

#: Earlier scheme names, refused with the current one in the message.
_RENAMED = {"forward": "euler", "symplectic": "symplectic_euler",
            "linearized": "linearized_backward_euler", "newton": "backward_euler"}


def check_scheme(name: str, choices: Sequence[str] = tuple(SCHEMES), what: str = "scheme") -> str:
    """Return ``name`` if it is one of ``choices``; a former name gets a message naming the
    current one."""
    if name in _RENAMED and name not in choices:
        raise ValueError(f"{what} {name!r} is now called {_RENAMED[name]!r}; {what} must be "
                         f"one of {', '.join(map(repr, choices))}")
    if name not in choices:
        raise ValueError(f"{what} must be one of {', '.join(map(repr, choices))}; got {name!r}")
    return name


def integrate(system: ImplicitSystem, state: State, h: float, scheme: str = "backward_euler",
              **options: Any) -> StepInfo:
    """Advance ``state`` by one step with the named scheme.

    Parameters
    ----------
    system, state, h
        As in :func:`euler`.
    scheme : {"euler", "symplectic_euler", "linearized_backward_euler", "backward_euler"}
        Integration scheme.
    **options
        Passed to the scheme (solver options of the implicit ones).

    Returns
    -------
    StepInfo
    """
    check_scheme(scheme)
    return SCHEMES[scheme](system, state, h, **options)
