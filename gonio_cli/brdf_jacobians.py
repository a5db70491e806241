"""The analytic Jacobians of the fits: ∂ log of each microfacet term of
:mod:`gonio_cli.brdf` with respect to the log of its width parameter.

The fits of :mod:`gonio_cli.fit` search the width (α, m) on a log scale; these closed
forms are the derivatives of the terms' logs, checked against finite differences by
``tests/test_fit_comparison.py``. The terms themselves (seed 000 eq. 3, seed 004 eq. 9,
the GGX Smith masking) are written once, in :mod:`gonio_cli.brdf`.
"""

from __future__ import annotations

import numpy as np

from .brdf import COS_EPS


def dlog_ggx_d_dlog_alpha(cos_theta_h, alpha) -> np.ndarray:
    """∂ log D / ∂ log α of seed 000 eq. (3): 2 − 4 α² cos²θh / (α² cos²θh + sin²θh).

    +2 far from the peak (D ∝ α² in the tails), −2 at cos θh = 1 (D ∝ 1/α² on the peak).
    Used for the analytic Jacobians of the fits.
    """
    ch = np.clip(np.asarray(cos_theta_h, dtype=float), 0.0, 1.0)
    a2c2 = np.asarray(alpha, dtype=float) ** 2 * ch * ch
    return 2.0 - 4.0 * a2c2 / (a2c2 + np.maximum(1.0 - ch * ch, 0.0))


def dlog_smith_g1_dlog_alpha(cos_theta, alpha) -> np.ndarray:
    """∂ log G1 / ∂ log α of the GGX Smith masking (:func:`gonio_cli.brdf.smith_g1_ggx`).

    G1 = 2c / (c + s), s = √(α² + (1 − α²) c²), so
    ∂ log G1/∂ log α = −α² (1 − c²) / (s (c + s)): 0 at normal incidence, → −1 at grazing.
    ``cos_theta``: (...,), clamped to [COS_EPS, 1].
    """
    c = np.clip(np.asarray(cos_theta, dtype=float), COS_EPS, 1.0)
    a2 = np.asarray(alpha, dtype=float) ** 2
    s = np.sqrt(a2 + (1.0 - a2) * c * c)
    return -a2 * (1.0 - c * c) / (s * (c + s))


def dlog_beckmann_dlog_m(cos_theta_h, m) -> np.ndarray:
    """∂ log D / ∂ log m of seed 004 eq. (9): 2 tan²θh / m² − 2. Shape as the broadcast
    of ``cos_theta_h[..., None]`` and ``m`` (as :func:`gonio_cli.brdf.beckmann_d`)."""
    ch = np.clip(np.asarray(cos_theta_h, dtype=float), COS_EPS, 1.0)[..., None]
    return 2.0 * (1.0 - ch * ch) / (ch * ch) / np.asarray(m, dtype=float) ** 2 - 2.0
