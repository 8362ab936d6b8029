"""The step-timeline figure's recording (docs/time-model.md): the tool's path and the burst."""

from pathlib import Path

from forcelearn.tools.figures.step_timeline import plot, record_step


def test_one_step_records_the_tool_moving_and_the_burst_after_it(tmp_path: Path) -> None:
    """The tool travels 4 mm in and 5 mm down within the step; the burst comes after it."""
    logs = record_step()
    start, end = logs["start_s"], logs["end_s"]
    times = [t for t, _, _ in logs["motion"]]
    assert times and all(start <= t <= end for t in times)
    (_, y0, z0), (_, y1, z1) = logs["motion"][0], logs["motion"][-1]
    assert abs((y1 - y0) - -4.0) < 0.1 and abs((z1 - z0) - -5.0) < 0.1
    samples = logs["samples"]
    assert len(samples) >= 3 and all(start <= s <= end for s in samples)
    assert samples[0] > max(t for t, y, _ in logs["motion"] if abs(y - y1) > 0.1)
    assert samples[-1] - samples[0] < 0.05  # one burst (25 ms), not the step
    assert plot(logs, tmp_path / "step.png").read_bytes().startswith(b"\x89PNG")
