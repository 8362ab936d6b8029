"""One-sigma uncertainties of a least-squares fit from its Jacobian.

``cov = (J^T J)^-1 B (J^T J)^-1`` with ``B = sum_g (J_g^T r_g)(J_g^T r_g)^T`` over
groups ``g`` of residuals (the trials): the cluster-robust ("sandwich") form, so
residuals that are correlated within a trial (the sensor's bias drift, what the
model misses about a pass) widen the uncertainty instead of being counted as
independent. Without groups each residual is its own. Taken through the SVD of
``J``, so a direction the residuals do not constrain gives an infinite
uncertainty (never a small one, as a pseudo-inverse would).
"""

from __future__ import annotations

import numpy as np

SINGULAR = 1e-9
"""Singular values below this share of the largest are directions the data do not see."""


def sigmas(jacobian: np.ndarray, residuals: np.ndarray,
           groups: np.ndarray | None = None, nuisance: int = 0) -> np.ndarray:
    """One-sigma uncertainty of each parameter (inf where the data do not constrain it).

    ``groups`` (one label per residual) marks residuals that may be correlated.
    ``nuisance``: parameters profiled out of the residuals (the sensor's bias segments,
    each with its walk term among them): the residuals' degrees of freedom are
    ``m - p - nuisance``, and the meat is scaled by ``m`` over that. The profiled biases
    take up part of each residual: with a bias per burst of an identification (its walk
    term beside it) the residuals left are smaller than the noise, and on a simulated
    step-and-hold with a walking zero the sandwich put the relaxation ratio at +- 0.0017
    where 40 draws scattered by 0.0023 (with the count: +- 0.0024).
    """
    m, p = jacobian.shape
    _, values, vt = np.linalg.svd(jacobian, full_matrices=False)
    largest = float(values[0]) if values.size else 0.0
    seen = values > SINGULAR * largest
    blind = np.zeros(p, bool)
    for k in np.flatnonzero(~seen):
        blind |= vt[k] ** 2 > 1e-12
    labels = np.arange(m) if groups is None else groups
    scores = jacobian * residuals[:, None]
    _, inverse = np.unique(labels, return_inverse=True)
    summed = np.zeros((int(inverse.max()) + 1 if m else 0, p))
    np.add.at(summed, inverse, scores)
    meat = summed.T @ summed * (m / max(1, m - p - nuisance))
    basis = vt[seen]  # (r, p)
    bread = basis.T / values[seen] ** 2 @ basis  # (J^T J)^-1 on the seen directions
    cov = bread @ meat @ bread
    result: np.ndarray = np.where(blind, np.inf, np.sqrt(np.maximum(np.diag(cov), 0.0)))
    return result


def largest_sigmas(jacobian: np.ndarray, residuals: np.ndarray,
                   groupings: list[np.ndarray | None], nuisance: int = 0) -> np.ndarray:
    """The largest 1-sigma of each parameter over several correlation structures.

    Each grouping is one guess at which residuals are correlated (:func:`sigmas`; None: each
    residual alone). Clustering by a level whose residuals are correlated negatively (errors
    that cancel within a trial along the fitted direction) shrinks the sandwich below the
    independent-residual one; residuals correlated along another level (a model error at one
    place of the path, met again on every pass) are seen by clustering at that level only.
    Not knowing which holds, the fit states the largest. ``nuisance``: :func:`sigmas`'.
    """
    result: np.ndarray = np.max(np.stack([sigmas(jacobian, residuals, g, nuisance)
                                          for g in groupings]), axis=0)
    return result
