"""The sensor's bias as a nuisance random walk, profiled out of the twin's fit.

A force sensor's zero drifts (thermally on a real one; the emulated JR3 and
Net F/T drift as a random walk, ``bias_drift_per_sqrt_s``) and a run zeroes it
only at its tares. The forward model predicts the force, not the bias, so
without this module the bias's wander over a run (~0.5 N over 60 trials)
lands in the residuals and leaks into the contact position and the wear.

Model: the bias is constant over a *segment* (a trial, or a slice of at most
``SEGMENT_S`` of a longer one such as the surface probe; once the members are fitted, each
burst of an identification, and of every trial where the walk is on,
:meth:`BiasWalk.at_bursts`) and walks between
segments: ``b_s - b_(s-1) ~ N(0, q^2 dt_s)``; it is 0 at every tare (the
run's own at its start, and each recorded accepted tare). For given model
predictions the biases minimise::

    sum_i w_i^2 (r_i - b_s(i))^2 + sum_s ((b_s - b_(s-1)) / (q sqrt(dt_s)))^2

(``r`` = recorded - predicted burst means), a tridiagonal system
(:func:`scipy.linalg.solve_banded`). The fit's residual vector becomes
``[w (r - b), the walk's terms]`` (variable projection: the finite-difference
Jacobian carries the biases' dependence on the parameters). Bursts where the
model predicts no contact (each trial's approach read, the probe's free
reads) read the bias alone, so they anchor it with no special case.

The drift rate ``q`` comes from the recorded tares when the run has at least
three (:func:`forcelearn.tools.twin.sensor.fit_sensor`), else from the
free-space reads of successive segments: ``var(increment) = q^2 dt +
var(read) + var(previous read)``, each read's variance from the noise, its
sample count and the noise's colour.

On held-out trials the biases come ONLY from the free-space reads (bursts the
twin predicts no contact for) and the walk from the last fitted trial, never
from the in-contact readings being predicted: the sensor's zero is not a
property of the cell; the twin reads it from the run's free-space readings as
a tare would.

Units: N, s, N/sqrt(s).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded
from scipy.optimize import least_squares, minimize_scalar

from forcelearn.emulators.physics.sponge_law import SpongeParams, penetration_mm
from forcelearn.records import TrialRecords
from forcelearn.tools.twin.arrays import RecordArrays
from forcelearn.tools.twin.forward import Reading
from forcelearn.tools.twin.sensor import SensorFit, mean_share, tare_reads, zero_variance

SEGMENT_S = 20.0
"""Longest stretch of cell time (s) over which the bias is taken as constant: a trial is
one segment; the surface probe (minutes) is sliced."""
FREE_MARGIN_MM = 1.5
"""A read is taken as free space for the drift's estimate when a plain spring fitted to
the reads (:func:`free_reads`), its surface raised by this much, has no contact there (mm):
it covers the waviness and relaxation the plain spring leaves out."""
DETECT_SIGMAS = 3.0
"""The walk is used (and its rate written to twin.toml) only when the measured drift is at
least this many of its sigmas above 0: read noise alone, over a short run, can put a
random walk's rate at 2 sigma, and a false walk soaks up the wear the records show."""
MIN_GAP_S = 1e-3
"""Floor of the walk's time between segments, s."""
UNKNOWN_ZERO_VAR_N2 = 1e6
"""The variance of a zero the records do not hold (N^2: known to +-1 kN, i.e. not at all):
the segment's bias is read from its own bursts (:func:`build_chain`'s ``unanchored``)."""

WeightsOf = Callable[[RecordArrays], np.ndarray]
"""The fit's weights (1 / expected scatter of each burst mean) of a data set, (T, M)."""


@dataclass(frozen=True)
class Chain:
    """The bias segments of one data set and how the walk links them.

    Segment ``s`` either follows segment ``s - 1`` after ``gap_s[s]`` seconds
    (``linked[s]``) or starts from the known value ``anchor_n[s]`` that long
    after a tare (or the previous data set's last segment), known to ``anchor_var_n2[s]``
    (a zero taken on a burst's mean is off by that mean's error).
    """

    segment: np.ndarray
    """(T, M) segment index of each burst, -1 where no burst."""
    trial_of: np.ndarray
    """(S,) trial number of each segment."""
    time_s: np.ndarray
    """(S,) mean cell time of each segment's bursts, s."""
    gap_s: np.ndarray
    """(S,) walk time from the previous segment or the anchor, s."""
    linked: np.ndarray
    """(S,) True: follows the previous segment; False: starts from ``anchor_n``."""
    anchor_n: np.ndarray
    """(S,) the bias the walk starts from where not linked, N."""
    anchor_var_n2: np.ndarray
    """(S,) the variance of that start where not linked (the zero's own error), N^2."""
    zero_of: np.ndarray
    """(S,) index into :class:`Zeros` of the zero each segment's bursts were read against
    (-1: none recorded)."""
    final_zero: int
    """The last zero taken by the data set's end (a zero check after its last burst)."""

    @property
    def size(self) -> int:
        """Number of segments."""
        return int(self.time_s.size)

    def variance(self, rate: float | np.ndarray) -> np.ndarray:
        """(S,) the walk's variance from each segment's start (previous segment or anchor), N^2.

        ``rate``: one q, N/sqrt(s), or one per segment.
        """
        result: np.ndarray = rate**2 * self.gap_s + np.where(self.linked, 0.0,
                                                              self.anchor_var_n2)
        return result


@dataclass(frozen=True)
class Zeros:
    """The run's accepted tares in record order (trial, then time): where the walk restarts."""

    trial: np.ndarray
    """(Z,) trial each was recorded in."""
    time_s: np.ndarray
    """(Z,) cell time, s: the zero holds for the bursts of moves that settled after it."""
    var_n2: np.ndarray
    """(Z,) variance of the zero's own error (its burst mean's), N^2."""
    rank: np.ndarray
    """(Z,) which of the trial's bursts at ``time_s`` the zero was taken on (-1: none): the
    bursts recorded after it at that time are read against it."""


@dataclass(frozen=True)
class After:
    """Where a data set's walk goes on from: the last segment of the data set before it."""

    time_s: float
    bias_n: float
    zero: int
    """The zero that segment was read against."""
    final_zero: int
    """The last zero taken by the end of that data set."""


def tare_zeros(records: list[TrialRecords], noise_n: float = math.nan,
               phi: float = 0.0) -> Zeros:
    """The accepted tares of ``records`` as :class:`Zeros`.

    A tare reads a burst and zeroes on it (the §5 run's zero check at every trial's END
    is a tare in software on that burst's mean): that mean's error, from ``noise_n`` and
    ``phi`` over the burst's samples (:func:`~forcelearn.tools.twin.sensor.zero_variance`),
    is where the walk after it starts; 0 without a noise or where the burst is not in the
    records.
    """
    reads = tare_reads(records)
    return Zeros(np.array([r.trial for r in reads], int),
                 np.array([r.time_s for r in reads], float),
                 np.array([zero_variance(noise_n, phi, r.count) for r in reads], float),
                 np.array([r.rank for r in reads], int))


def _ranks(data: RecordArrays, settled: np.ndarray) -> np.ndarray:
    """(T, M) each burst's place among its trial's bursts recorded at its settled time."""
    ranks = np.full(settled.shape, -1)
    seen: dict[tuple[int, float], int] = {}
    for row, col in zip(*np.nonzero(data.has_burst), strict=True):
        key = (int(data.trial[row]), float(settled[row, col]))
        ranks[row, col] = seen.get(key, 0)
        seen[key] = ranks[row, col] + 1
    return ranks


def build_chain(data: RecordArrays, zeros: Zeros, after: After | None = None,
                unanchored: frozenset[int] = frozenset(),
                per_burst: frozenset[int] = frozenset()) -> Chain:
    """Segments of ``data`` and their links.

    A zero (a tare) holds for the bursts read after the one it was taken on: of later
    moves, or recorded after it at the same time (the cell's clock does not run during a
    read: a tare's own burst settled at the tare's time, and so may the reads after it);
    a trial's zeros taken after its last burst hold for the next trial. A segment
    read against another zero than the segment before restarts the walk from 0 at that
    zero. (Taking each trial's tare as its start pinned every trial's bias to 0, over a
    1 ms gap, where the tare is the zero check at the trial's end.) ``after`` is the last
    fitted segment, for held-out trials; without it and without a zero the first segment
    starts from 0 at the first move (the run's tare at its start). Cell time running
    backwards at a trial's start (the next run directory) restarts the walk from 0.
    ``unanchored``: trials whose zero is not in the records (an identification's: it tares
    before its records start, in a session of its own) starts from an unknown bias
    (``UNKNOWN_ZERO_VAR_N2``), read from its own bursts; the row after it of another trial
    starts from the run's tare. ``per_burst``: trials whose bursts are each a segment of
    their own (the walk followed from burst to burst, :meth:`BiasWalk.at_bursts`).
    """
    burst_s = np.where(data.has_burst, data.burst_start_s + 0.5 * data.burst_span_s, np.nan)
    settled = np.where(np.isfinite(data.settled_s), data.settled_s, data.burst_start_s)
    ranks = _ranks(data, settled)
    segment = np.full(data.has_burst.shape, -1)
    trial_of: list[int] = []
    members: list[list[float]] = []
    zero_s: list[float] = []  # per segment: when its walk starts (NaN: the previous segment)
    anchors: list[float] = []
    anchor_vars: list[float] = []
    zero_of: list[int] = []
    ids_of: dict[int, list[int]] = {}
    for index, number in enumerate(zeros.trial.tolist()):
        ids_of.setdefault(int(number), []).append(index)
    passed: dict[int, int] = {}  # trial -> how many of its zeros the chain has passed
    current = after.final_zero if after is not None else -1
    previous_end = after.time_s if after is not None else -math.inf
    previous_trial: int | None = None
    for row in range(data.trials):
        trial = int(data.trial[row])
        ids = ids_of.get(trial, [])
        columns = np.flatnonzero(data.has_burst[row])
        columns = columns[np.argsort(settled[row, columns], kind="stable")]  # as recorded
        starts = data.start_s[row][data.valid[row]]
        row_start = (float(np.nanmin(starts)) if np.isfinite(starts).any() else
                     float(burst_s[row, columns[0]]) if columns.size else math.nan)
        for k, col in enumerate(columns):
            done = passed.get(trial, 0)
            while done < len(ids) and (
                    zeros.time_s[ids[done]] < settled[row, col]
                    or (zeros.time_s[ids[done]] == settled[row, col]
                        and zeros.rank[ids[done]] < ranks[row, col])):
                current, done = ids[done], done + 1
            passed[trial] = done
            moment = float(burst_s[row, col])
            longest = 0.0 if trial in per_burst else SEGMENT_S
            if (k == 0 or moment - members[-1][0] > longest
                    or (members and current != zero_of[-1])):
                var = 0.0
                if k == 0 and trial in unanchored and previous_trial != trial:
                    zero, anchor, var = row_start, 0.0, UNKNOWN_ZERO_VAR_N2
                elif not members and after is not None and current == after.zero:
                    zero, anchor = after.time_s, after.bias_n
                elif current >= 0 and (not members or current != zero_of[-1]):
                    zero, anchor = float(zeros.time_s[current]), 0.0
                    var = float(zeros.var_n2[current])
                elif not members or (k == 0 and (row_start < previous_end
                                                  or previous_trial in unanchored)):
                    zero, anchor = row_start, 0.0  # the run's tare at its start
                else:
                    zero, anchor = math.nan, 0.0
                trial_of.append(trial)
                members.append([])
                zero_s.append(zero)
                anchors.append(anchor)
                anchor_vars.append(var)
                zero_of.append(current)
            members[-1].append(moment)
            segment[row, col] = len(members) - 1
            previous_end = moment
            previous_trial = trial
        last_of_trial = row + 1 == data.trials or int(data.trial[row + 1]) != trial
        if last_of_trial and passed.get(trial, 0) < len(ids):  # taken after its last burst
            current = ids[-1]
            passed[trial] = len(ids)
    times = np.array([float(np.mean(m)) for m in members])
    zeros_at = np.array(zero_s)
    linked = np.isnan(zeros_at)
    before = np.concatenate([[math.nan], times[:-1]])
    gaps = np.maximum(MIN_GAP_S, times - np.where(linked, before, zeros_at))
    return Chain(segment, np.array(trial_of, int), times, gaps, linked, np.array(anchors),
                 np.array(anchor_vars), np.array(zero_of, int), current)


def solve_biases(chain: Chain, residual_n: np.ndarray, weights: np.ndarray,
                 rate: float | np.ndarray) -> np.ndarray:
    """The segment biases (S,) minimising the weighted misfit plus the walk's penalty.

    ``residual_n`` is recorded - predicted (T, M); ``weights`` (T, M) are 0 where a
    burst must not inform the bias (NaN residuals count as weight 0). ``rate`` is
    the walk's q, N/sqrt(s), or one per segment (:meth:`BiasWalk.rates`: a walk that
    restarts at an anchor keeps one q up to the next); at 0 every bias is its anchor.
    """
    if chain.size == 0:
        return np.zeros(0)
    rates = np.broadcast_to(np.asarray(rate, float), (chain.size,))
    walks = rates > 0
    if walks.all():
        return _walked_biases(chain, residual_n, weights, rates)
    still = _still_biases(chain, residual_n, weights)
    if not walks.any():
        return still
    walked = _walked_biases(chain, residual_n, weights, np.where(walks, rates, 1.0))
    result: np.ndarray = np.where(walks, walked, still)
    return result


def _still_biases(chain: Chain, residual_n: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """:func:`solve_biases` without a walk (q = 0)."""
    s_count = chain.size
    base = np.where(chain.linked, 0.0, chain.anchor_n)
    # no walk: a linked segment keeps its head's bias (the last anchored segment's),
    # which is its zero's value within that zero's own error (a tare on a burst's mean
    # is off by that mean's error: the probe's zeros on one burst of a noisy sensor
    # are off by a few tenths of a newton), read from the group's bursts
    head = np.maximum.accumulate(np.where(chain.linked, 0, np.arange(s_count)))
    use = (chain.segment >= 0) & (weights > 0) & np.isfinite(residual_n)
    group = head[chain.segment[use]]
    w2 = weights[use] ** 2
    sum_w2 = np.bincount(group, w2, minlength=s_count)
    sum_w2r = np.bincount(group, w2 * residual_n[use], minlength=s_count)
    var = chain.anchor_var_n2
    known = np.divide(1.0, var, out=np.zeros(s_count), where=var > 0)
    values = np.where(var > 0, (sum_w2r + known * base) / (sum_w2 + known + (var <= 0)),
                      base)
    result_: np.ndarray = values[head]
    return result_


def _walked_biases(chain: Chain, residual_n: np.ndarray, weights: np.ndarray,
                   rates: np.ndarray) -> np.ndarray:
    """:func:`solve_biases` with a walk of q ``rates`` (S,) > 0."""
    s_count = chain.size
    use = (chain.segment >= 0) & (weights > 0) & np.isfinite(residual_n)
    index = chain.segment[use]
    w2 = weights[use] ** 2
    sum_w2 = np.bincount(index, w2, minlength=s_count)
    sum_w2r = np.bincount(index, w2 * residual_n[use], minlength=s_count)
    precision = 1.0 / chain.variance(rates)
    diagonal = sum_w2 + precision
    following = np.where(chain.linked, precision, 0.0)
    diagonal[:-1] += following[1:]
    rhs = sum_w2r + np.where(chain.linked, 0.0, precision * chain.anchor_n)
    banded = np.zeros((3, s_count))
    banded[0, 1:] = -following[1:]
    banded[1] = diagonal
    banded[2, :-1] = -following[1:]
    result: np.ndarray = solve_banded((1, 1), banded, rhs)
    return result


def walk_terms(chain: Chain, biases: np.ndarray, rate: float | np.ndarray) -> np.ndarray:
    """The walk's residuals ``(b_s - b_(s-1)) / sqrt(q^2 dt_s (+ the zero's variance))`` (S,).

    At q = 0 a linked segment's term is 0 (it keeps its head's bias), an anchored one's its
    zero's prior, ``(b_s - anchor) / sqrt(var)`` (0 for an exact zero). ``rate``: one q,
    or one per segment.
    """
    if chain.size == 0:
        return np.zeros(0)
    rates = np.broadcast_to(np.asarray(rate, float), (chain.size,))
    walks = rates > 0
    var = chain.anchor_var_n2
    scale = np.sqrt(np.where(var > 0, var, 1.0))
    still: np.ndarray = np.where(~chain.linked & (var > 0),
                                 (biases - chain.anchor_n) / scale, 0.0)
    if not walks.any():
        return still
    before = np.concatenate([[0.0], biases[:-1]])
    start = np.where(chain.linked, before, chain.anchor_n)
    walked = (biases - start) / np.sqrt(chain.variance(np.where(walks, rates, 1.0)))
    result: np.ndarray = np.where(walks, walked, still)
    return result


def offsets(chain: Chain, biases: np.ndarray) -> np.ndarray:
    """The bias of each burst (T, M), 0 where no burst."""
    padded = np.concatenate([biases, [0.0]])
    result: np.ndarray = padded[chain.segment]  # -1 picks the padded 0
    return result


@dataclass(frozen=True)
class DriftEstimate:
    """The bias's random-walk rate q and where it came from."""

    rate: float
    """N/sqrt(s); NaN when nothing measures it."""
    sigma: float
    """1-sigma, N/sqrt(s); inf when not measured."""
    source: str
    """"tares", "free-space reads" or "none"."""
    reads: int
    """Segments with a free-space read (or tares) that measured it."""
    allowed: float = math.nan
    """The largest rate the measurement allows at 1 sigma, N/sqrt(s) (NaN: not known)."""

    @property
    def detected(self) -> bool:
        """The rate stands ``DETECT_SIGMAS`` sigmas clear of 0 (:func:`drift_detected`)."""
        return drift_detected(self.rate, self.sigma)


def drift_detected(rate: float, sigma: float) -> bool:
    """A measured drift ``rate`` (N/sqrt(s)) with 1-sigma ``sigma`` is told from no drift."""
    return math.isfinite(rate) and rate > 0 and rate > DETECT_SIGMAS * sigma


def drift_from_reads(chain: Chain, free: np.ndarray, data: RecordArrays, noise_n: float,
                     phi: float) -> DriftEstimate:
    """The drift rate q from the free-space reads of successive segments (maximum likelihood).

    Each segment's free reads give its bias (their variance-weighted mean, variance
    from the noise, their sample counts and the noise's colour). The reads are a
    random walk (from 0 at each tare) seen through that read noise: a local-level
    model whose likelihood a scalar Kalman filter gives (:func:`walk_log_likelihood`);
    q maximises it, and its 1-sigma is the likelihood's curvature there. A
    single-sample approach read (noise 0.2 N) is far noisier than one trial's walk
    (0.02 N/sqrt(s) over 16 s: 0.08 N): successive increments hardly tell q, the
    walk over many trials does. The moment estimate this replaces put a 300-trial
    default run's 0.019 N/sqrt(s) at 0.011 +- 0.004, "not told from no drift", and
    the walk was switched off.
    """
    noise = noise_n if math.isfinite(noise_n) else 0.0
    share = np.vectorize(lambda n: mean_share(phi, float(n)))
    use = free & data.has_burst & (chain.segment >= 0) & np.isfinite(data.mean_n)
    if not use.any():
        return DriftEstimate(math.nan, math.inf, "none", 0)
    index = chain.segment[use]
    variance = np.maximum(noise**2 * share(data.count[use]), 1e-12)
    precision = np.bincount(index, 1.0 / variance, minlength=chain.size)
    total = np.bincount(index, data.mean_n[use] / variance, minlength=chain.size)
    measured = precision > 0
    safe = np.where(measured, precision, 1.0)
    moment = np.where(data.has_burst, data.burst_start_s + 0.5 * data.burst_span_s, 0.0)[use]
    reads = ReadSeries(
        value=np.where(measured, total / safe, np.nan),
        variance=np.where(measured, 1.0 / safe, np.nan),
        time_s=np.bincount(index, moment / variance, minlength=chain.size) / safe,
        restart_s=np.where(chain.linked, np.nan, chain.time_s - chain.gap_s),
        anchor_n=chain.anchor_n,
        anchor_var_n2=chain.anchor_var_n2,
    )
    count = int(measured.sum())
    if count < 3:
        return DriftEstimate(math.nan, math.inf, "none", count)
    rate, sigma = walk_rate(reads)
    return DriftEstimate(rate, sigma, "free-space reads", count)


def walk_rate(reads: ReadSeries) -> tuple[float, float]:
    """The maximum-likelihood walk rate of ``reads`` and its 1-sigma (curvature), N/sqrt(s)."""
    top = max(1e-6, 10.0 * math.sqrt(np.nanmax(reads.value**2)))
    best = minimize_scalar(lambda log_q: -walk_log_likelihood(reads, math.exp(log_q)),
                           bounds=(math.log(1e-6), math.log(top)), method="bounded",
                           options={"xatol": 1e-4})
    rate = math.exp(float(best.x))
    step = 1e-3 * max(rate, 1e-4)
    lows = [walk_log_likelihood(reads, max(rate + k * step, 0.0)) for k in (-1, 0, 1)]
    curvature = (2 * lows[1] - lows[0] - lows[2]) / step**2
    return rate, (1.0 / math.sqrt(curvature) if curvature > 0 else math.inf)


@dataclass(frozen=True)
class ReadSeries:
    """The segments' bias reads for the drift's likelihood, (S,) each; NaN: no read."""

    value: np.ndarray
    """The segment's bias read, N."""
    variance: np.ndarray
    """Its variance from the read noise, N^2."""
    time_s: np.ndarray
    """When it was read, s."""
    restart_s: np.ndarray
    """Where the walk restarts before the segment (a tare), s; NaN: it goes on."""
    anchor_n: np.ndarray
    """The bias the walk restarts from, N."""
    anchor_var_n2: np.ndarray
    """Its variance (the zero's own error), N^2."""


def walk_log_likelihood(reads: ReadSeries, rate: float) -> float:
    """Log-likelihood of the reads under a random walk of ``rate`` N/sqrt(s) (Kalman filter)."""
    total = 0.0
    level, spread, last = 0.0, 0.0, math.nan
    for s in range(reads.value.size):
        if not math.isnan(reads.restart_s[s]):
            level, spread = float(reads.anchor_n[s]), float(reads.anchor_var_n2[s])
            last = float(reads.restart_s[s])
        value = reads.value[s]
        if math.isnan(value):
            continue
        now = float(reads.time_s[s])
        if not math.isnan(last):
            spread += rate * rate * max(now - last, MIN_GAP_S)
        last = now
        innovation_var = spread + float(reads.variance[s])
        error = float(value) - level
        total -= 0.5 * (math.log(2 * math.pi * innovation_var) + error * error / innovation_var)
        gain = spread / innovation_var
        level += gain * error
        spread *= 1.0 - gain
    return total


FRESH_MIN_CONTACTS = 6
"""Contact reads (> ``CONTACT_FLOOR_N``) the probe's rows need to stand for the fresh foam."""
CONTACT_FLOOR_N = 0.5


def _fresh_rows(data: RecordArrays) -> np.ndarray:
    """(T,) True for the rows whose bursts stand for the fresh foam (:func:`free_reads`)."""
    stepping = (data.is_step & data.valid).any(axis=1)
    probe: np.ndarray = ~stepping
    contacts = probe[:, None] & data.has_burst & (np.nan_to_num(data.mean_n) > CONTACT_FLOOR_N)
    if contacts.sum() >= FRESH_MIN_CONTACTS:
        return probe
    every: np.ndarray = np.ones(data.trials, bool)
    return every


def free_reads(data: RecordArrays, base: dict[str, float], reading: Reading) -> np.ndarray:
    """(T, M) True for bursts read in free space, for the drift's estimate.

    A plain spring ``F = k max(0, s + a (z_top - z) - y)`` (the fresh surface, its
    slope, one stiffness) is fitted to the bursts of the fresh foam; a burst is free
    where that surface raised by ``FREE_MARGIN_MM`` is below the tool (or the tool is
    off the strip). It needs no starting guess from the full fit and no wear: wear only
    lowers the surface, so a burst above the fresh one is free. The fresh foam's
    bursts are the surface probe's (rows without control steps, several depths at
    several places) when they hold ``FRESH_MIN_CONTACTS`` contact reads, else every
    burst: a plain spring fitted to a long run's worn foam puts the surface mm too high
    (a 300-trial default run: 5.8 mm for 0, k 0.89 for 2 N/mm) and takes every approach
    read for contact, which switched the bias walk off; the trials' steps alone, all near
    one force, leave stiffness and surface to trade off, so they are used only without
    a probe.
    """
    use = data.has_burst & np.isfinite(data.mean_n) & _fresh_rows(data)[:, None]
    y, z = data.reached[..., 1][use], data.reached[..., 2][use]
    travelled = base["z_top_mm"] - z
    along = abs(reading.along_y) or 1.0
    force = data.mean_n[use] / along

    def misfit(x: np.ndarray) -> np.ndarray:
        result: np.ndarray = x[0] * np.maximum(0.0, x[1] + x[2] * travelled - y) - force
        return result

    start = np.array([base["stiffness_n_per_mm"], base["surface_y_mm"], 0.0])
    fitted = least_squares(misfit, start, bounds=([1e-3, -1e3, -0.5], [1e3, 1e3, 0.5]),
                           ).x
    surface = {**base, "surface_y_mm": float(fitted[1]) + FREE_MARGIN_MM,
               "surface_slope": float(fitted[2]), "waviness_mm": 0.0, "set_mm": 0.0}
    depth = penetration_mm(SpongeParams.unchecked(surface), data.passes,
                           data.reached[..., 1], data.reached[..., 2])
    free: np.ndarray = data.has_burst & (np.nan_to_num(depth, nan=1.0) <= 0.0)
    return free


@dataclass(frozen=True)
class BiasWalk:
    """The bias profile of one fit: the fitted trials' chain, the held-out trials', q."""

    train: Chain
    heldout_data: RecordArrays
    zeros: Zeros
    train_weights: np.ndarray
    heldout_weights: np.ndarray
    drift: DriftEstimate
    trial_labels: np.ndarray
    """(T, M) trial number of each fitted burst (the uncertainty's groups)."""
    train_mean_n: np.ndarray
    """(T, M) recorded burst means of the fitted trials, N."""
    unanchored: frozenset[int] = frozenset()
    """Fitted trials whose zero is not in the records (an identification's)."""

    @property
    def rate(self) -> float:
        """The q the profile uses (0: no walk, each bias stays at its zero's, within its error)."""
        return self.drift.rate if self.drift.detected else 0.0

    def rates(self, chain: Chain) -> float | np.ndarray:
        """The q of each segment of ``chain`` (one q: the same for all), N/sqrt(s).

        :attr:`rate`; where the drift is not told from 0, an unanchored trial's segments (an
        identification's: minutes at one place, read against a zero nobody recorded) walk at
        the largest rate the tares allow (:attr:`DriftEstimate.allowed`). Held still there,
        its one bias took the zero's walk over the identification into the contact: the
        identifications of the hidden cells read 0.10 N more in their first contacts than
        in the free space before them (their emulated sensors walk alike: each runs with
        seed 0), and at the truth the identification's bursts of seed 1's cells 03, 07, 08
        and 16 pulled the surface up by 0.7-1.3 of its sigma; walking, by -0.01 to +0.10.
        """
        allowed = self.drift.allowed
        if self.rate > 0 or not self.unanchored or not allowed > 0:
            return self.rate
        result: np.ndarray = np.where(np.isin(chain.trial_of, sorted(self.unanchored)),
                                      allowed, 0.0)
        return result

    def residuals(self, error_n: np.ndarray, keep: np.ndarray | None = None) -> np.ndarray:
        """The fit's residual vector for ``error_n`` = predicted - recorded (T, M).

        ``[w (predicted + b - recorded)] `` over the fitted bursts, then the walk's terms.
        ``keep`` (T, M) bool: only those bursts count (the others weigh 0, a resampled fit).
        """
        weights = self.train_weights if keep is None else np.where(keep, self.train_weights, 0.0)
        rates = self.rates(self.train)
        biases = solve_biases(self.train, -error_n, weights, rates)
        use = self.train.segment >= 0
        misfit = ((error_n + offsets(self.train, biases)) * weights)[use]
        return np.concatenate([misfit, walk_terms(self.train, biases, rates)])

    def groups(self) -> np.ndarray:
        """One trial label per entry of :meth:`residuals` (the walk's term: its segment's)."""
        use = self.train.segment >= 0
        return np.concatenate([self.trial_labels[use], self.train.trial_of])

    def debiased(self, train_pred: np.ndarray, heldout_pred: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Predictions with the bias added.

        The fitted trials' biases come from all their bursts; the held-out trials'
        from their free-space reads only (the model predicts 0 there) and the walk
        from the last fitted trial.
        """
        train_b = solve_biases(self.train, self.train_mean_n - train_pred,
                               self.train_weights, self.rates(self.train))
        last = (After(float(self.train.time_s[-1]), float(train_b[-1]),
                      int(self.train.zero_of[-1]), self.train.final_zero)
                if self.train.size else None)
        chain = build_chain(self.heldout_data, self.zeros, last)
        free = self.heldout_data.has_burst & (np.nan_to_num(heldout_pred, nan=1.0) == 0.0)
        weights = np.where(free, self.heldout_weights, 0.0)
        residual = self.heldout_data.mean_n - heldout_pred
        held_b = solve_biases(chain, residual, weights, self.rate)
        held = heldout_pred + offsets(chain, held_b)
        return train_pred + offsets(self.train, train_b), held

    @property
    def profiled(self) -> int:
        """Biases profiled out of :meth:`residuals` (each with its walk or prior term there).

        With a walk, one per segment; without, one per segment the walk restarts at with a
        zero known only to its error (a linked segment shares its head's, an exact zero none).
        """
        walks = np.broadcast_to(np.asarray(self.rates(self.train)) > 0, (self.train.size,))
        still = ~walks & ~self.train.linked & (self.train.anchor_var_n2 > 0)
        return int(np.sum(walks) + np.sum(still))

    def at_bursts(self, data: RecordArrays) -> BiasWalk:
        """The same walk with each burst its own segment (the unanchored trials': every one's).

        Of the unanchored trials always; of every trial where the walk is on. The surface
        probe's points dwell at one place for a minute and more while the zero walks
        ``q sqrt(20 s)`` (0.09 N at 0.02 N/sqrt(s)) inside a 20 s slice, against burst means
        known to a few hundredths of a newton. Held over the slices, the probe's bursts of
        hidden cells 12 of seed 3 and 06 of seed 2 pulled the surface up by 2.1 and 2.3 of
        its sigma at the truth (every hidden cell's sensor walks alike: each runs with seed
        0); burst by burst, by 0.9 and 1.1. On cell 13 of seed 2 they pulled the surface
        slope and contact and with them the relaxation ratio (at the truth, with everything the
        nonlinear member frees, ratio -4.3 sigma; the probe per burst, -2.3).

        A run's own trials too (since 2026-12-05, twentieth session): a trial of 10-20 s
        is one segment, while its zero walks from the trial's tare by ``q sqrt(t)`` (0.07 N
        over 12 s at 0.02 N/sqrt(s)) under burst means known to 0.01 N. Hidden cell 02 of
        seed 6 (a 0.056 N sensor) reported its softening 3.7 sigma low (0.1719 +- 0.0016
        against 0.1777); per burst, 2.4 sigma (0.1747 +- 0.0013); over other sensor seeds
        see docs/twin-fit.md, "Session 20".
        ``data``: the fitted trials this walk was built on.
        """
        fine = self.unanchored
        if self.rate > 0:
            fine = fine | frozenset(int(t) for t in np.unique(data.trial))
        if not fine:
            return self
        chain = build_chain(data, self.zeros, unanchored=self.unanchored, per_burst=fine)
        return dataclasses.replace(self, train=chain)

    def sensor(self, fit: SensorFit) -> SensorFit:
        """``fit`` with the drift the walk measured when the tares did not."""
        if fit.tares >= 3 and math.isfinite(fit.drift_n_per_sqrt_s):
            return fit
        return dataclasses.replace(fit, drift_n_per_sqrt_s=self.drift.rate,
                                   drift_sigma=self.drift.sigma,
                                   drift_source=self.drift.source)


def bias_walk(records: list[TrialRecords], train: RecordArrays, heldout: RecordArrays,
              base: dict[str, float], reading: Reading, sensor: SensorFit,
              weights_of: WeightsOf, phi: float | None) -> BiasWalk:
    """The bias profile for a fit: chains, weights and q (from tares, else free reads).

    ``base`` is the fit's base sponge (its strip's ends, a start for
    :func:`free_reads`).
    """
    zeros = tare_zeros(records, sensor.noise_n, phi if phi is not None else 0.0)
    # trials fitted beside the run's (an identification's) whose tares are not in its records
    unanchored = frozenset(int(t) for t in np.unique(train.trial)) - {t.trial for t in records}
    chain = build_chain(train, zeros, unanchored=unanchored)
    if sensor.tares >= 3 and math.isfinite(sensor.drift_n_per_sqrt_s):
        drift = DriftEstimate(sensor.drift_n_per_sqrt_s, sensor.drift_sigma, "tares",
                              sensor.tares, sensor.drift_allowed)
    else:
        free = free_reads(train, base, reading)
        drift = drift_from_reads(chain, free, train, sensor.noise_n,
                                 phi if phi is not None else 0.0)
    labels = np.broadcast_to(train.trial[:, None], train.has_burst.shape)
    return BiasWalk(chain, heldout, zeros, weights_of(train), weights_of(heldout), drift,
                    labels, train.mean_n, unanchored)
