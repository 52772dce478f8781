"""Tests of filters.kernels: normalisation, gradients against finite differences, support."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from filters import kernels as K

SMOOTH = ["cubic", "wendland", "poly6", "spiky"]
ALL = SMOOTH + ["viscosity"]
SCALAR = {
    "cubic": (K.cubic_w, K.cubic_dw),
    "wendland": (K.wendland_w, K.wendland_dw),
    "poly6": (K.poly6_w, K.poly6_dw),
    "spiky": (K.spiky_w, K.spiky_dw),
    "viscosity": (K.viscosity_w, K.viscosity_dw),
}


@pytest.mark.parametrize("name", SMOOTH)
def test_integrates_to_one_on_a_fine_lattice(name):
    h = 0.7
    s = h / 40.0
    n = int(math.ceil(h / s))
    g = (np.arange(-n, n + 1)) * s
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    r = np.sqrt(X * X + Y * Y + Z * Z)
    total = K.kernel_value(name, r, h).sum() * s ** 3
    assert abs(total - 1.0) < 1e-3


@pytest.mark.parametrize("name", ALL)
def test_integrates_to_one_radially(name):
    h = 1.3
    w = SCALAR[name][0]
    total, _ = quad(lambda r: 4.0 * math.pi * r * r * w(r, h), 0.0, h, limit=200,
                    points=[0.5 * h])
    assert abs(total - 1.0) < 1e-6


@pytest.mark.parametrize("name", ALL)
def test_radial_derivative_matches_finite_differences(name):
    h = 0.9
    w, dw = SCALAR[name]
    eps = 1e-6
    for r in np.linspace(0.05, 0.95, 37) * h:
        fd = (w(r + eps, h) - w(r - eps, h)) / (2 * eps)
        assert dw(r, h) == pytest.approx(fd, rel=1e-5, abs=1e-6 / h ** 4)


@pytest.mark.parametrize("name", ALL)
def test_gradient_matches_finite_differences(name):
    h = 0.5
    rng = np.random.default_rng(1)
    d = rng.uniform(-0.35, 0.35, size=(200, 3))
    d = d[np.linalg.norm(d, axis=1) > 0.02 * h]
    grad = K.kernel_gradient(name, d, h)
    eps = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        fd = (K.kernel_value(name, np.linalg.norm(d + e, axis=1), h)
              - K.kernel_value(name, np.linalg.norm(d - e, axis=1), h)) / (2 * eps)
        scale = np.abs(fd).max()
        np.testing.assert_allclose(grad[:, k], fd, rtol=1e-5, atol=1e-7 * scale)


@pytest.mark.parametrize("name", ["poly6", "viscosity"])
def test_laplacian_matches_finite_differences(name):
    h = 0.8
    w = SCALAR[name][0]
    eps = 1e-4
    r = np.linspace(0.1, 0.9, 17) * h
    # radial Laplacian: W'' + 2 W' / r
    d2 = np.array([(w(x + eps, h) - 2 * w(x, h) + w(x - eps, h)) / eps ** 2 for x in r])
    d1 = np.array([(w(x + eps, h) - w(x - eps, h)) / (2 * eps) for x in r])
    np.testing.assert_allclose(K.kernel_laplacian(name, r, h), d2 + 2 * d1 / r, rtol=1e-5)


@pytest.mark.parametrize("name", ALL)
def test_compact_support(name):
    h = 0.25
    w, dw = SCALAR[name]
    r = np.array([h, h * (1 + 1e-12), 1.5 * h, 10 * h])
    assert (K.kernel_value(name, r, h) == 0.0).all()
    d = np.array([[h, 0, 0], [0, 2 * h, 0], [h, h, h]])
    assert (K.kernel_gradient(name, d, h) == 0.0).all()
    for x in r:
        assert w(x, h) == 0.0 and dw(x, h) == 0.0
    # continuous at the support's edge
    assert w(h * (1 - 1e-6), h) < 1e-9 / h ** 3
    if name != "viscosity":
        assert K.kernel_value(name, np.array([0.0]), h)[0] > 0.0


def test_cubic_spline_values_match_monaghan():
    h = 2.0  # smoothing length 1
    sigma = 1.0 / math.pi  # 3-D normalisation for smoothing length 1
    # Monaghan 1992, q = r / (h/2): 1 - 1.5 q^2 + 0.75 q^3 for q <= 1; 0.25 (2 - q)^3 for q <= 2
    for q in np.linspace(0, 1.99, 30):
        ref = sigma * (1 - 1.5 * q ** 2 + 0.75 * q ** 3 if q <= 1 else 0.25 * (2 - q) ** 3)
        assert K.cubic_w(q, h) == pytest.approx(ref, rel=1e-12, abs=1e-15)


def test_cohesion_repels_close_attracts_far_and_vanishes():
    h = 1.0
    assert K.cohesion_c(0.2, h) < 0.0
    assert K.cohesion_c(0.7, h) > 0.0
    assert K.cohesion_c(1.0, h) == 0.0 and K.cohesion_c(1.5, h) == 0.0
    # continuous at h / 2
    assert K.cohesion_c(0.5 - 1e-9, h) == pytest.approx(K.cohesion_c(0.5 + 1e-9, h), rel=1e-6)
    assert K.adhesion_a(0.4, h) == 0.0 and K.adhesion_a(0.75, h) > 0.0


def test_bad_arguments():
    with pytest.raises(ValueError, match="kernel"):
        K.kernel_value("gauss", [0.1], 1.0)
    with pytest.raises(ValueError, match="h must be"):
        K.kernel_value("cubic", [0.1], 0.0)
    with pytest.raises(TypeError, match="h must be"):
        K.kernel_value("cubic", [0.1], "1")
    with pytest.raises(ValueError, match="shape"):
        K.kernel_gradient("cubic", np.zeros((3, 2)), 1.0)
    with pytest.raises(ValueError, match="Laplacian"):
        K.kernel_laplacian("cubic", [0.1], 1.0)
