"""One thread for small work: the elastic kernels' shared guard around Numba parallel regions."""

from __future__ import annotations

from contextlib import contextmanager
from typing import TYPE_CHECKING

import numba

if TYPE_CHECKING:
    from collections.abc import Iterator

__all__ = ["serial_below"]


@contextmanager
def serial_below(work: int, minimum: int) -> Iterator[None]:
    """Run the enclosed Numba parallel kernels on one thread when ``work < minimum``.

    Below a few thousand items a parallel region costs more than the work it shares, and on a
    busy machine one descheduled worker stalls every region; the results do not depend on the
    thread count either way (the kernels are written without races).
    """
    if work >= minimum:
        yield
        return
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)
