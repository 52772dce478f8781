"""Shared fixtures.  Rendering and ParaView tests run with no DISPLAY, as in CI."""

import os

import numpy as np
import pytest

os.environ.pop("DISPLAY", None)


@pytest.fixture
def rng():
    """A seeded random generator, so every test sees the same numbers."""
    return np.random.default_rng(20261121)
