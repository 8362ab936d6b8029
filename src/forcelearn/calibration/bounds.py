"""Physical bounds of every value in a calibration file, checked at load beside the digest.

The digest proves a file is the one that was written, not that what was written
is physically possible: a hand-made file with a correct digest (or a bug in a
writer) could carry ``cutoff_hz = 1e9`` or a tool of 10^6 kg, and the cell
would subtract that tool's weight from every reading. :func:`check_bounds`
refuses each such value as :class:`~forcelearn.errors.ConfigError` naming its
key and the bound. The bounds and their reasons are in docs/calibration.md
("Physical bounds"); most follow from the sensor's own full scales, which
``check_full_scales`` has already bounded.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from forcelearn.calibration.model import STANDARD_GRAVITY_M_S2, Calibration
from forcelearn.errors import ConfigError

MAX_CUTOFF_HZ = 10_000.0
"""Highest low-pass cut-off (Hz): the Nyquist frequency of twice the fastest F/T stream
known (JR3 DSP 8 kHz, Net F/T 7 kHz, Axia 7.9 kHz)."""
MAX_RATE_HZ = 1.0e6
"""Highest achieved sample rate (Hz). The rate is counted on the host's clock, and an
emulated sensor delivers faster than a real one (about 21 kHz seen), so the bound is
the host's: a million timestamps a second; the rate is a record, not used."""
MAX_DURATION_S = 86_400.0
"""Longest noise recording (s): a day; the command records seconds."""
MAX_SAMPLES = 10**9
"""Most samples in a recording or at a pose (a day at ~11.6 kHz)."""
READING_SPAN = 2.0
"""A reading is at most this many full scales (a JR3 counts to twice its full scale)."""
MAX_COM_MM = 2000.0
"""Largest centre-of-mass coordinate (mm): a tool reaching 2 m from the flange is beyond
any robot's wrist load diagram."""
MOMENT_SPAN = 2.0
"""The tool's largest gravity moment m*g*|c| is at most this many moment full scales:
beyond it the tool saturates the sensor in most orientations and could not be fitted."""
MAX_CONDITION_NUMBER = 1.0e6
"""Largest design-matrix condition number (the command refuses above 20 by default)."""
MAX_MATRIX_ENTRY = 10.0
"""Largest |C_ij| of the matrix check: C maps readings to applied loads and is near
the identity; a sensor off by ten times on an axis is not calibrated, it is broken."""
MIN_LOADS, MAX_LOADS = 12, 10**6


def _fail(source: str, key: str, value: object, bound: str) -> ConfigError:
    return ConfigError(f"{source}: {key} = {value} is out of bounds: {bound}; the file "
                       "cannot come from a real calibration; run `forcelearn calibrate` again")


def _within(source: str, key: str, values: Sequence[float], limits: Sequence[float],
            why: str, unit: str = "") -> None:
    """Refuse ``key`` when some |value| exceeds its axis's limit."""
    for i, (value, limit) in enumerate(zip(values, limits, strict=True)):
        if not abs(value) <= limit:
            name = f"{key}[{i}]" if len(values) > 1 else key
            raise _fail(source, name, f"{value:g}{unit}", f"|value| <= {limit:g}{unit} ({why})")


def _range(source: str, key: str, value: float, low: float, high: float, unit: str,
           why: str, above: bool = False) -> None:
    ok = (low < value if above else low <= value) and value <= high and math.isfinite(value)
    if not ok:
        sign = "<" if above else "<="
        raise _fail(source, key, f"{value:g} {unit}".rstrip(),
                    f"{low:g} {sign} value <= {f'{high:g} {unit}'.rstrip()} ({why})")


def check_bounds(cal: Calibration, source: str = "calibration") -> None:
    """Refuse a calibration with a value no sensor, tool or fit can produce.

    Raises:
        ConfigError: names the key (``tool.mass_kg``, ``noise.bias[2]``...), the
            value and the bound.
    """
    s, n, t = cal.sensor, cal.noise, cal.tool
    fs = tuple(float(v) for v in s.full_scales)
    force_fs, moment_fs = max(fs[:3]), max(fs[3:])
    span = tuple(v * READING_SPAN for v in fs)
    _range(source, "sensor.cutoff_hz", s.cutoff_hz, 0.0, MAX_CUTOFF_HZ, "Hz",
           "no filter passes more than the Nyquist frequency of the fastest sensor", above=True)
    # noise: a mean after zeroing and a spread are readings: within the full scale
    _within(source, "noise.bias", n.bias, fs, "the mean after zeroing is a reading "
            "within the full scale")
    variances = np.diag(np.asarray(n.covariance))
    _within(source, "noise.covariance diagonal", variances.tolist(), tuple(v * v for v in fs),
            "a noise standard deviation beyond the full scale is no sensor")
    _within(source, "noise.drift_per_s", n.drift_per_s, fs,
            "a drift of the full scale each second is no sensor", " per s")
    _range(source, "noise.duration_s", n.duration_s, 0.0, MAX_DURATION_S, "s",
           "a recording of up to a day", above=True)
    _range(source, "noise.rate_hz", n.rate_hz, 0.0, MAX_RATE_HZ, "Hz",
           "a host timestamps no faster", above=True)
    _range(source, "noise.samples", n.samples, 10, MAX_SAMPLES, "", "recorded samples")
    # tool: its weight and gravity moment must fit the sensor's range
    most_kg = force_fs / STANDARD_GRAVITY_M_S2
    _range(source, "tool.mass_kg", t.mass_kg, 0.0, most_kg, "kg",
           f"the tool's weight m*g must not exceed the largest force full scale, "
           f"{force_fs:g} N", above=True)
    _range(source, "tool.mass_std_kg", t.mass_std_kg, 0.0, most_kg, "kg",
           "an uncertainty larger than any possible mass says nothing")
    _within(source, "tool.com_mm", t.com_mm, (MAX_COM_MM,) * 3,
            "a centre of mass 2 m from the sensor is no robot tool", " mm")
    _within(source, "tool.com_std_mm", t.com_std_mm, (MAX_COM_MM,) * 3,
            "an uncertainty larger than any possible offset says nothing", " mm")
    moment = t.mass_kg * STANDARD_GRAVITY_M_S2 * float(np.linalg.norm(t.com_mm)) / 1000.0
    if moment > MOMENT_SPAN * moment_fs:
        raise _fail(source, "tool.com_mm", list(t.com_mm),
                    f"the tool's gravity moment m*g*|c| = {moment:g} N*m must be <= "
                    f"{MOMENT_SPAN:g} x the largest moment full scale ({moment_fs:g} N*m)")
    _within(source, "tool.force_bias_n", t.force_bias_n, fs[:3],
            "F0 is minus a reading within the full scale", " N")
    _within(source, "tool.force_bias_std_n", t.force_bias_std_n, fs[:3],
            "an uncertainty beyond the full scale says nothing", " N")
    _within(source, "tool.torque_bias_nm", t.torque_bias_nm, fs[3:],
            "M0 is minus a reading within the full scale", " N*m")
    _within(source, "tool.torque_bias_std_nm", t.torque_bias_std_nm, fs[3:],
            "an uncertainty beyond the full scale says nothing", " N*m")
    _range(source, "tool.condition_number", t.condition_number, 1.0, MAX_CONDITION_NUMBER,
           "", "a fit this ill-conditioned determines nothing")
    for i, pose in enumerate(t.poses):
        key = f"tool.pose[{i}]"
        _range(source, f"{key}.samples", pose.samples, 0, MAX_SAMPLES, "",
               "0 when the fit was not told")
        _within(source, f"{key}.mean", pose.mean, span,
                f"a reading is at most {READING_SPAN:g} full scales")
        _within(source, f"{key}.residual", pose.residual, span,
                f"a residual beyond {READING_SPAN:g} full scales is no fit")
    if cal.matrix_check is not None:
        m = cal.matrix_check
        _range(source, "matrix_check.loads", m.loads, MIN_LOADS, MAX_LOADS, "", "known loads")
        for r, row in enumerate(m.matrix):
            _within(source, f"matrix_check.matrix[{r}]", row, (MAX_MATRIX_ENTRY,) * 6,
                    "C is near the identity")
        _within(source, "matrix_check.rms_residual_fit", m.rms_residual_fit, span,
                f"an RMS beyond {READING_SPAN:g} full scales is no fit")
        _within(source, "matrix_check.rms_residual_sensor", m.rms_residual_sensor, span,
                f"an RMS beyond {READING_SPAN:g} full scales is no sensor")
