"""Seed 000 eq. 5's D/4 and the normalised Phong lobe, each written once: the forms the
fits, lobes and renderer call agree with hand formulas and with each other."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.brdf import (EQ5_QUARTER, goniochromatic, goniochromatic_d4,
                            goniochromatic_d4_into, goniochromatic_exponent_arg,
                            log_goniochromatic_d4)
from gonio_cli.geometry import Cosines
from gonio_cli.lobes import cosine_lobe, lobe_integral, phong_lobe, phong_normalisation

ALPHAS = (0.05, 0.18, 0.6, 1.0)


def hand_d4(ch, alpha):
    """α² / (4π ((α² − 1) cos²θh + 1)²), seed 000 eqs. 3 and 5 as printed."""
    a2 = alpha * alpha
    return a2 / (4.0 * np.pi * ((a2 - 1.0) * ch * ch + 1.0) ** 2)


def scratch_of(dtype):
    buffers = {}

    def scratch(name, m, dt=None):
        return buffers.setdefault((name, dt), np.empty(m, dt or dtype))
    return scratch


@pytest.mark.parametrize("alpha", ALPHAS)
def test_d4_forms_agree_with_the_printed_formula(alpha):
    ch = np.linspace(0.0, 1.0, 1001)
    # float64: only round-off (the hand form cancels near cos θh = 1 for small α: 1e-12)
    np.testing.assert_allclose(goniochromatic_d4(ch, alpha), hand_d4(ch, alpha), rtol=1e-12)
    np.testing.assert_allclose(np.exp(log_goniochromatic_d4(ch, alpha)), hand_d4(ch, alpha),
                               rtol=1e-12)
    np.testing.assert_allclose(goniochromatic_d4_into(ch.copy(), alpha, scratch_of(np.float64)),
                               hand_d4(ch, alpha), rtol=1e-12)
    # the renderer's float32 path: ~10 float32 operations, each ≤ 6e-8 relative
    d32 = goniochromatic_d4_into(ch.astype(np.float32), alpha, scratch_of(np.float32))
    assert d32.dtype == np.float32
    np.testing.assert_allclose(d32, hand_d4(ch.astype(np.float32).astype(float), alpha),
                               rtol=2e-6)
    assert EQ5_QUARTER == 0.25


def test_eq5_is_d4_times_the_goniochromatic_term(rng):
    ci, co = rng.uniform(0.05, 1.0, 200), rng.uniform(0.05, 1.0, 200)
    ch, cd = rng.uniform(0.3, 1.0, 200), rng.uniform(0.3, 1.0, 200)
    rho, c = rng.uniform(0.01, 0.5, 41), rng.uniform(-3.0, 5.0, 41)
    f = goniochromatic(Cosines(ci, co, ch, cd), 0.2, rho, c)
    x = goniochromatic_exponent_arg(ci, co)
    np.testing.assert_allclose(f, goniochromatic_d4(ch, 0.2)[:, None] * rho
                               * np.exp(c * x[:, None]), rtol=1e-13)


@pytest.mark.parametrize("n", [1.0, 4.0, 70.0, 1e4])
def test_phong_lobe_is_the_normalised_power_and_reflects_all_at_normal_incidence(n):
    c = np.array([-1.0, -1e-9, 0.0, 1e-3, 0.5, 0.9, 0.999, 1.0])
    expected = (n + 2.0) / (2.0 * np.pi) * np.maximum(c, 0.0) ** n
    with np.errstate(under="ignore"):
        np.testing.assert_allclose(phong_lobe(c, n), expected, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(phong_normalisation(n), (n + 2.0) / (2.0 * np.pi), rtol=1e-15)
    # ∫ f cos θ dω at normal incidence (R = N): 2π ∫₀¹ f(μ) μ dμ = 1, and
    # ∫ max(0, r·ω)^E dω = 2π/(E+1): 64-node Gauss–Legendre on [0, 1] is exact for
    # polynomials of degree ≤ 127, so only round-off remains (E = 1e4: the closed form)
    if n < 100:
        t, w = np.polynomial.legendre.leggauss(64)
        mu, w = 0.5 * (t + 1.0), 0.5 * w
        assert 2.0 * np.pi * np.sum(w * phong_lobe(mu, n) * mu) == pytest.approx(1.0, rel=1e-12)
        assert 2.0 * np.pi * np.sum(w * cosine_lobe(mu, [n])[:, 0]) == \
            pytest.approx(float(lobe_integral(n)), rel=1e-12)
    assert float(lobe_integral(n)) == pytest.approx(2.0 * np.pi / (n + 1.0), rel=1e-15)
