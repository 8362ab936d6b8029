"""BiasWatch: a reading the step's move cannot explain is suspect; the foam's changes are not."""

from __future__ import annotations

import pytest

from forcelearn.devices import Pose
from forcelearn.errors import SensorSuspect
from forcelearn.tasks.bias_watch import (
    FREE_MARGIN_N,
    MARGIN_N,
    PRESS_MARGIN_N,
    STIFFNESS_BAND_N_PER_MM,
    BiasWatch,
)

K_LOW, K_HIGH = STIFFNESS_BAND_N_PER_MM


def at(y_mm: float) -> Pose:
    """The pose commanded at ``y_mm``."""
    return Pose(0.0, y_mm, 0.0)


def pressed(watch: BiasWatch, force_n: float = 12.0, y_mm: float = -4.0) -> None:
    """The trial's first press, read in contact."""
    watch(("approach", 0), at(y_mm), force_n)


def test_changes_a_stiffness_in_the_band_explains_pass() -> None:
    """1 mm deeper: anything from the band's softest to its stiffest, within the margin."""
    watch = BiasWatch()
    pressed(watch)
    watch(("step", 1), at(-5.0), 12.0 + K_HIGH + 0.9 * MARGIN_N)
    watch(("step", 2), at(-6.0), 12.0 + K_HIGH + K_LOW)
    watch(("step", 3), at(-2.0), 0.0)  # eased off out of the foam: it never pulls
    assert (watch.checked, watch.suspects) == (3, 0)


@pytest.mark.parametrize("jump_n", [-1.2 * MARGIN_N, 1.2 * MARGIN_N])
def test_a_step_with_no_move_that_jumps_is_suspect(jump_n: float) -> None:
    """The same Y, the force steps by more than the margin: a bias step, either way."""
    watch = BiasWatch()
    pressed(watch)
    with pytest.raises(SensorSuspect, match="bias step"):
        watch(("step", 1), at(-4.0), 12.0 + jump_n)
    assert watch.suspects == 1


def test_only_consecutive_steps_from_contact_are_judged() -> None:
    """From free space, across trials or stages, nothing is known of the next force."""
    watch = BiasWatch()
    pressed(watch, force_n=0.2)  # the press read free space: no reference
    watch(("step", 1), at(-4.0), 30.0)
    watch(("step", 3), at(-4.0), 0.0)  # step 2 not read
    watch(("retreat", 0), at(15.0), 0.0)
    watch(("step", 1), at(-4.0), 30.0)
    assert watch.checked == 0


def test_a_step_between_trials_shows_at_the_next_first_press() -> None:
    """The same press pose: a 1.5 N difference is suspect, unless the sensor was zeroed between."""
    watch = BiasWatch()
    pressed(watch)
    watch(("step", 1), at(-5.0), 14.0)
    pressed(watch, force_n=12.3)  # the next trial: as before, within the press margin
    with pytest.raises(SensorSuspect):
        pressed(watch, force_n=12.3 + 1.25 * PRESS_MARGIN_N)
    pressed(watch, force_n=12.0, y_mm=-4.0)
    watch(("approach", 0), at(-4.0), 16.0, zeros=1)  # a zero came between: a new reference
    assert watch.suspects == 1


def test_free_space_at_the_retract_plane_must_read_zero() -> None:
    """At or above the retract plane nothing touches: more than the free margin is suspect."""
    watch = BiasWatch(free_y_mm=15.0)
    watch(("probe", 0), at(15.0), 0.9 * FREE_MARGIN_N)
    with pytest.raises(SensorSuspect, match="zero moved"):
        watch(("probe", 1), at(15.0), -1.5 * FREE_MARGIN_N)
    watch(("probe", 1), at(14.0), 3.0)  # below the plane: not known to be free
    assert (watch.checked, watch.suspects) == (2, 1)


def test_a_stiff_part_the_probe_measured_is_not_a_bias_step() -> None:
    """8 N/mm over a 1 mm step is suspect for the example sponge's band, not once fitted to it."""
    step_n = 8.0 * 1.0
    assert step_n > K_HIGH * 1.0 + MARGIN_N  # the default band cannot explain it
    default = BiasWatch()
    pressed(default)
    with pytest.raises(SensorSuspect):
        default(("step", 1), at(-5.0), 12.0 + step_n)
    fitted = BiasWatch()
    fitted.fit_to_probe([6.5, 8.0, 7.2], hysteresis_loss=0.0, force_n=12.0)
    pressed(fitted)
    fitted(("step", 1), at(-5.0), 12.0 + step_n)
    with pytest.raises(SensorSuspect):  # a jump with no move is still seen
        fitted(("step", 2), at(-5.0), 12.0 + step_n + 1.2 * fitted.margin_n)


def test_a_hysteretic_foam_widens_the_margin_by_its_branch_gap() -> None:
    """Easing off on h = 0.25 at 20 N drops 2 h F = 10 N more than the elastic law: not suspect."""
    watch = BiasWatch()
    watch.fit_to_probe([2.0], hysteresis_loss=0.25, force_n=20.0)
    pressed(watch, force_n=20.0)
    watch(("step", 1), at(-3.5), 20.0 - K_HIGH * 0.5 - 9.0)
    assert watch.suspects == 0


def test_fitting_never_narrows_the_defaults() -> None:
    """A soft-only probe keeps the default band's high end; no hysteresis keeps the margin."""
    watch = BiasWatch()
    watch.fit_to_probe([1.0], hysteresis_loss=float("nan"), force_n=20.0)
    assert watch.band[0] < K_LOW and watch.band[1] == K_HIGH and watch.margin_n == MARGIN_N


def test_the_example_sponges_probe_keeps_the_measured_defaults() -> None:
    """Points of 1.7-2.3 N/mm (the example's 2 N/mm +- 15 %): band and margins as measured."""
    watch = BiasWatch()
    watch.fit_to_probe([1.7, 2.0, 2.3], hysteresis_loss=0.0, force_n=19.6)
    assert watch.band == STIFFNESS_BAND_N_PER_MM
    assert (watch.margin_n, watch.press_margin_n) == (MARGIN_N, PRESS_MARGIN_N)


def test_the_margin_grows_with_the_probed_stiffness() -> None:
    """A stiff part's unexplained depth (its surface between steps) reads as more force."""
    watch = BiasWatch()
    watch.fit_to_probe([8.0], hysteresis_loss=0.0, force_n=29.4)
    assert watch.margin_n > MARGIN_N and watch.press_margin_n > PRESS_MARGIN_N
    pressed(watch, force_n=29.4)
    watch(("step", 1), at(-3.66), 29.4 + 3.0)  # eased off 0.34 mm, the surface rose 0.7 mm
    with pytest.raises(SensorSuspect):
        watch(("step", 2), at(-3.66), 32.4 + 1.2 * watch.margin_n)


def test_a_false_alarm_widens_the_margins_it_tripped() -> None:
    """After a zero check found the zero in place, the same move's change is no longer suspect."""
    watch = BiasWatch()
    pressed(watch)
    with pytest.raises(SensorSuspect):
        watch(("step", 1), at(-4.0), 12.0 - 1.2 * MARGIN_N)
    watch.widen(1.5)
    pressed(watch)
    watch(("step", 1), at(-4.0), 12.0 - 1.2 * MARGIN_N)
    assert (watch.false_alarms, watch.margin_n) == (1, 1.5 * MARGIN_N)
    with pytest.raises(ValueError):
        watch.widen(1.0)


def test_a_drop_easing_off_is_judged_when_the_tool_presses_back_to_its_depth() -> None:
    """A hysteretic foam's unloading drop passes; a bias step down is caught pressing back."""
    gap_n = 3.0 * MARGIN_N  # an unloading branch's drop after a reversal (2 h F)
    watch = BiasWatch()
    pressed(watch, force_n=20.0, y_mm=-6.0)
    watch(("step", 1), at(-5.5), 20.0 - 0.5 * K_HIGH - gap_n)  # eased off: dropped to its branch
    watch(("step", 2), at(-6.0), 20.0)  # pressed back: on the loading branch again
    assert watch.suspects == 0 and watch.deferred == 1

    stepped = BiasWatch()
    pressed(stepped, force_n=20.0, y_mm=-6.0)
    stepped(("step", 1), at(-5.5), 20.0 - 0.5 * K_HIGH - gap_n)  # a step down, easing off
    with pytest.raises(SensorSuspect, match="bias step"):
        stepped(("step", 2), at(-6.0), 20.0 - gap_n)  # pressed back: still off by the step
