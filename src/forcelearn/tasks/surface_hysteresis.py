"""The foam's hysteresis as the probe sees it: press in, ease off, fit the branch ratio and depth.

At each probe point the probe presses in (the loading branch: readings after a
dwell, so relaxed) and then eases off from its deepest Y by growing amounts e
(``[probe] ease_off_mm``), reading after the same dwell. A hysteretic foam
answers the easing off on its unloading branch: at the same depth, less force.
With the branch law of a rate-independent (Dahl-type) foam, the state s goes
from +1 (loading) towards −1 within a few branch depths d_h of a reversal,
s(e) = −1 + 2 exp(−e / d_h), and the force is (1 + h s) times the elastic one,
so an eased-off reading over the loading force at the same Y is

    ρ(e) = (1 + h s(e)) / (1 + h)

(the loading force at that Y: the press readings interpolated in Y, which holds
for a foam that stiffens too). :func:`fit_hysteresis` fits h (the loss: the
loading branch is (1 + h), the unloading (1 − h) times the elastic force; the
energy lost per cycle is about 2h / (1 + h) of the loading work) and d_h (mm)
by least squares, each with its standard error. A fit whose h is within
:data:`RESOLVED_SIGMAS` standard errors of 0, or whose largest branch gap is
within that many times the readings' noise, **cannot tell hysteresis from
noise** and says so (``resolved`` False); the task then moves straight to its
steps as the paper's does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import curve_fit

RESOLVED_SIGMAS = 3.0
"""h is resolved when it and the largest branch gap pass this many standard errors."""
MAX_DEPTH_MM = 10.0
"""Largest branch depth d_h the fit considers, mm."""
MIN_DEPTH_MM = 0.01
"""Smallest branch depth d_h the fit considers, mm."""


@dataclass(frozen=True)
class HysteresisFit:
    """The loss h and the branch depth d_h fitted at the probe's points (NaN: not fitted)."""

    loss: float
    """h: loading (1 + h), unloading (1 − h) times the elastic force."""
    loss_std: float
    depth_mm: float
    """d_h: the depth change over which a reversal switches branch, mm."""
    depth_std: float
    gap_n: float
    """The largest loading − unloading force difference read at one Y, N."""
    noise_n: float
    """The readings' force noise the gap is judged against (the fit's residual), N."""
    readings: int
    """Eased-off readings fitted."""
    resolved: bool
    """True when the readings tell hysteresis from noise (module docstring)."""

    @property
    def energy_loss(self) -> float:
        """Share of the loading work a full cycle loses, 2h / (1 + h)."""
        return 2.0 * self.loss / (1.0 + self.loss)

    def describe(self) -> str:
        """One line for a log or a diagnosis."""
        if not self.resolved:
            return (f"hysteresis not resolved from noise: h = {self.loss:.3f} ± {self.loss_std:.3f}"
                    f", largest branch gap {self.gap_n:.2f} N against {self.noise_n:.2f} N noise "
                    f"({self.readings} eased-off readings)")
        return (f"hysteresis h = {self.loss:.3f} ± {self.loss_std:.3f} (energy loss "
                f"{100 * self.energy_loss:.0f} %), branch depth {self.depth_mm:.2f} ± "
                f"{self.depth_std:.2f} mm, largest gap {self.gap_n:.2f} N")


NOT_FITTED = HysteresisFit(math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, 0, False)
"""No eased-off readings (``[probe] ease_off_mm`` empty, or an old probe)."""


def branch_ratio(ease_mm: np.ndarray, loss: float, depth_mm: float) -> np.ndarray:
    """ρ(e): eased-off force over loading force at the same Y (module docstring)."""
    state = -1.0 + 2.0 * np.exp(-np.asarray(ease_mm, float) / depth_mm)
    return np.asarray((1.0 + loss * state) / (1.0 + loss), dtype=float)


def fit_hysteresis(
    ease_mm: np.ndarray, unloaded_n: np.ndarray, loaded_n: np.ndarray, noise_n: float
) -> HysteresisFit:
    """Fit h and d_h to eased-off readings against the loading force at the same Y.

    Args:
        ease_mm: how far each reading eased off from the deepest press, mm (> 0).
        unloaded_n: the eased-off readings, N.
        loaded_n: the loading branch's force at the same Y, N (> 0).
        noise_n: a floor on the readings' force noise, N (the fit's residual counts too).
    """
    e = np.asarray(ease_mm, float)
    f_u = np.asarray(unloaded_n, float)
    f_l = np.asarray(loaded_n, float)
    keep = (e > 0) & (f_l > 0) & np.isfinite(f_u)
    e, f_u, f_l = e[keep], f_u[keep], f_l[keep]
    if len(e) < 2:
        return NOT_FITTED
    ratio = f_u / f_l
    gap = float(np.max(f_l - f_u))
    guess = (min(max(float((1 - np.min(ratio)) / (1 + np.min(ratio))), 0.01), 0.9),
             max(float(np.median(e)), MIN_DEPTH_MM))
    try:
        coef, cov = curve_fit(
            branch_ratio, e, ratio, p0=guess, sigma=1.0 / f_l, absolute_sigma=False,
            bounds=([0.0, MIN_DEPTH_MM], [0.95, MAX_DEPTH_MM]),
        )
    except (RuntimeError, ValueError):
        return HysteresisFit(math.nan, math.nan, math.nan, math.nan, gap, noise_n, len(e), False)
    loss, depth = float(coef[0]), float(coef[1])
    residual = f_u - f_l * branch_ratio(e, loss, depth)
    noise = max(noise_n, math.sqrt(float(np.mean(residual**2))))
    stds = np.sqrt(np.clip(np.diag(cov), 0.0, None)) if np.all(np.isfinite(cov)) else [math.inf] * 2
    loss_std, depth_std = float(stds[0]), float(stds[1])
    if len(e) == 2:  # as many readings as unknowns: no residual to judge by
        loss_std = depth_std = math.inf
    resolved = loss > RESOLVED_SIGMAS * loss_std and gap > RESOLVED_SIGMAS * noise
    return HysteresisFit(loss, loss_std, depth, depth_std, gap, noise, len(e), resolved)
