"""Memory estimates checked before a large allocation: refuse up front instead of swapping.

A set-up that would need more memory than the machine has (a spacing a tenth of the default, a
million hair strands) is refused with a :class:`MemoryLimitError` naming the estimate and the
limit, before any array is allocated.  The limit is 80 % of the memory available when the check
runs (``MemAvailable`` on Linux), or the environment variable ``BLOBFLOW_MAX_MEMORY`` (bytes, or
a number with a unit: ``512M``, ``16G``, ``1.5GiB``) to raise or lower it.
"""

from __future__ import annotations

import math
import os
import re

__all__ = ["MemoryLimitError", "available_memory", "memory_limit", "check_memory",
           "format_bytes", "MEMORY_ENV"]

#: Environment variable overriding the memory limit (bytes, or a number with K/M/G/T units).
MEMORY_ENV = "BLOBFLOW_MAX_MEMORY"
_UNITS = {"": 1, "b": 1, "k": 2**10, "kb": 2**10, "kib": 2**10, "m": 2**20, "mb": 2**20,
          "mib": 2**20, "g": 2**30, "gb": 2**30, "gib": 2**30, "t": 2**40, "tb": 2**40,
          "tib": 2**40}


class MemoryLimitError(ValueError):
    """A set-up would need more memory than the limit (see :func:`memory_limit`)."""


def format_bytes(n: float) -> str:
    """``n`` bytes as a short human-readable size with three significant digits (``1.5 GiB``)."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024.0 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024.0
    return f"{n:.3g} PiB"  # pragma: no cover - the loop always returns


def available_memory() -> int:
    """Memory (bytes) the system can give a new allocation now without swapping."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):  # not POSIX: assume a modest machine
        return 4 * 2**30


def _parse_size(text: str) -> int:
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([a-zA-Z]*)\s*", text)
    unit = match.group(2).lower() if match else None
    if match is None or unit not in _UNITS:
        raise ValueError(f"{MEMORY_ENV} must be a size such as 8G, 512MiB or 1e9, got {text!r}")
    value = float(match.group(1)) * _UNITS[unit]
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{MEMORY_ENV} must be a positive size, got {text!r}")
    return int(value)


def memory_limit() -> int:
    """The most memory (bytes) one set-up may plan to use.

    ``BLOBFLOW_MAX_MEMORY`` when set, otherwise 80 % of :func:`available_memory`.
    """
    text = os.environ.get(MEMORY_ENV, "").strip()
    if text:
        return _parse_size(text)
    return int(0.8 * available_memory())


def check_memory(what: str, n_bytes: float, hint: str = "") -> None:
    """Raise :class:`MemoryLimitError` if ``n_bytes`` exceeds :func:`memory_limit`.

    Parameters
    ----------
    what : str
        What needs the memory, e.g. ``"spacing 0.0004 m: 3.5e+07 particles"``.
    n_bytes : float
        The estimate (bytes).
    hint : str
        How to need less, appended to the message.
    """
    limit = memory_limit()
    if n_bytes > limit:
        source = (f"{MEMORY_ENV}" if os.environ.get(MEMORY_ENV, "").strip()
                  else f"80 % of the {format_bytes(available_memory())} available; set "
                       f"{MEMORY_ENV} to change it")
        raise MemoryLimitError(
            f"{what} needs about {format_bytes(n_bytes)}, above the memory limit of "
            f"{format_bytes(limit)} ({source})" + (f"; {hint}" if hint else ""))
