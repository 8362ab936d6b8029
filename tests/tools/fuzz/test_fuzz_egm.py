"""Bounded runs of the ``egm`` fuzz target: hostile datagrams to the real driver over loopback UDP.

The long run (>= 10^5 inputs) is documented in docs/fuzzing.md.
"""

from __future__ import annotations

import random
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from forcelearn.devices import Pose
from forcelearn.protocols.egm import codec
from forcelearn.tools.fuzz import egm as fuzz_egm
from forcelearn.tools.fuzz.egm import FuzzFailure
from forcelearn.tools.fuzz.targets import apply_mutations, random_mutations


def mutate(data: bytes, rng: random.Random) -> bytes:
    """The harness's byte mutations."""
    return apply_mutations(data, random_mutations(rng))


@pytest.fixture(params=[("rw7", False), ("rw6", True)], ids=["rw7-first-sender", "rw6-configured"])
def rig(request: pytest.FixtureRequest) -> Iterator[fuzz_egm.EgmRig]:
    """A driver with its session open, RW7 paired by its first sender or RW6 configured."""
    version, pinned = request.param
    opened = fuzz_egm.EgmRig.open(version, pinned)
    yield opened
    opened.close()


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**32))
def test_hostile_inputs_never_end_the_session_nor_move_the_plan_beyond_the_ramp(
    rig: fuzz_egm.EgmRig, seed: int
) -> None:
    """20 hostile inputs per example: every property of the target holds."""
    rng = random.Random(seed)
    for _ in range(20):
        fuzz_egm.check_egm(rig, fuzz_egm.random_egm_input(rng, rig, mutate))


def test_the_ramp_check_catches_a_jump(rig: fuzz_egm.EgmRig) -> None:
    """The property is not vacuous: a planned pose 2 mm from the last is reported."""
    assert rig.planned is not None
    jumped = codec.SensorMessage((rig.reply_seqno or 0) + 1, 0, rig.planned.moved(dz_mm=2.0))
    with pytest.raises(FuzzFailure, match="jump"):
        rig._check_reply(jumped)


def test_the_workspace_check_catches_a_pose_outside(rig: fuzz_egm.EgmRig) -> None:
    """A planned pose at x = 2500 mm on the wire is reported."""
    outside = codec.SensorMessage(1, 0, Pose(2500.0, 0.0, 600.0, fuzz_egm.HOME.quaternion))
    with pytest.raises(FuzzFailure, match="outside the workspace"):
        rig._check_reply(outside)


def test_an_answer_to_another_host_is_caught(rig: fuzz_egm.EgmRig) -> None:
    """Anything received by the other hosts' sockets is reported."""
    rig.controller.sendto(b"x", rig.others[0].getsockname())
    rig.others[0].settimeout(1.0)
    data = rig.others[0].recv(10)  # wait until it is there, then put the check to work
    rig.others[1].sendto(data, rig.others[0].getsockname())
    with pytest.raises(FuzzFailure, match="not the controller"):
        for _ in range(100):
            rig.drain_others()
