"""The emulated cell's state: saved under each kind's name, and old checkpoints still read."""

from __future__ import annotations

from forcelearn.site import CellSession, load_cell_config


def test_an_old_checkpoints_link_key_still_restores_the_computer_link() -> None:
    """Checkpoints written before the kinds had one name saved the computer link as "link"."""
    config = load_cell_config()
    with CellSession(config, seed=0) as moved:
        assert moved.cell is not None
        moved.cell.move_in_steps(config.task.start_pose(), config.safety.max_step_mm)
        state = moved.emulator_state()
    assert {"clock", "sponge", "computer_link", "jr3"} <= set(state) and "link" not in state
    old = {("link" if key == "computer_link" else key): value for key, value in state.items()}
    with CellSession(config, seed=0) as resumed:
        before = resumed.emulator_state()["computer_link"]
        resumed.load_emulator_state(old)
        after = resumed.emulator_state()["computer_link"]
    assert before != state["computer_link"]  # the moves changed it: the restore is seen
    assert after == state["computer_link"]
