"""When the controller does not guide: the error the driver raises, and what the operator does."""

from __future__ import annotations

from forcelearn.errors import GuidanceStopped
from forcelearn.protocols.egm import codec


def require_running(m: codec.RobotMessage) -> None:
    """Raise ``GuidanceStopped`` unless ``m`` says motors on, EGM running and RAPID running.

    RAPID_UNDEFINED is accepted, as abb_libegm does (a controller-restart quirk).
    """
    if (
        m.motor is not codec.MotorState.ON
        or m.mci is not codec.MciState.RUNNING
        or m.rapid is codec.RapidState.STOPPED
    ):
        raise GuidanceStopped(
            f"the controller is not guided: motors {m.motor.name}, EGM {m.mci.name}, "
            f"RAPID {m.rapid.name}; {what_to_do(m)}"
        )


def what_to_do(m: codec.RobotMessage) -> str:
    """What the operator must do for the controller to guide again, by what stopped it."""
    if m.motor is not codec.MotorState.ON:
        return ("the motors are off (an emergency or protective stop?): clear the stop, switch "
                "the motors on and start the ForcelearnEGM RAPID program (PP to Main), then "
                "resume the run (it retracts first)")
    if m.rapid is codec.RapidState.STOPPED:
        return ("the RAPID program stopped (from the FlexPendant, or a RAPID error other than a "
                "comm timeout: see the controller's event log): start ForcelearnEGM again "
                "(PP to Main), then resume the run (it retracts first)")
    return ("EGM is not running: after a comm timeout the shipped ForcelearnEGM module opens a "
            "new session by itself within about 1 s and the run waits for it; if none comes, "
            "check the controller's event log, the PC address and firewall of its UCdevice")
