"""The installed blobflow's version (``blobflow --version``)."""

from __future__ import annotations

__all__ = ["version"]


def version() -> str:
    """The version of the installed ``blobflow`` distribution (``pyproject.toml``), or
    ``"unknown"`` when the package runs from a folder that was never installed."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as distribution_version

    try:
        return distribution_version("blobflow")
    except PackageNotFoundError:
        return "unknown"
