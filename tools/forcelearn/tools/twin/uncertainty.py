"""One-sigma uncertainties of a least-squares fit from its Jacobian.

``cov = s^2 (J^T J)^-1`` with ``s^2`` the residuals' variance per degree of
freedom, taken through the SVD of ``J`` so that a direction the residuals do
not constrain gives an infinite uncertainty (never a small one, as a
pseudo-inverse would).
"""

from __future__ import annotations

import numpy as np

SINGULAR = 1e-9
"""Singular values below this share of the largest are directions the data do not see."""


def sigmas(jacobian: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """One-sigma uncertainty of each parameter (inf where the data do not constrain it)."""
    m, p = jacobian.shape
    dof = max(1, m - p)
    scale = float(np.sum(residuals**2)) / dof
    _, values, vt = np.linalg.svd(jacobian, full_matrices=False)
    largest = float(values[0]) if values.size else 0.0
    out = np.zeros(p)
    for k, value in enumerate(values):
        weight = vt[k] ** 2
        if value <= SINGULAR * largest or value == 0.0:
            out = np.where(weight > 1e-12, np.inf, out)
            continue
        out = out + weight / value**2
    result: np.ndarray = np.sqrt(out * scale)
    return result
