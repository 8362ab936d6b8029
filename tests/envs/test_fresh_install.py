"""`gymnasium.make("forcelearn...")` from the installed wheel, not from the source tree."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_gymnasium_make_works_from_a_fresh_install_of_the_wheel(tmp_path: Path) -> None:
    """Build the wheel, install it into an empty target, and make both envs from there only.

    The subprocess drops the editable install's source folders from ``sys.path``,
    so forcelearn is imported from what ``pip install`` put in the target.
    """
    wheel_dir, target = tmp_path / "wheel", tmp_path / "site"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--quiet"]
    subprocess.run(
        [*pip, "wheel", "--no-deps", "--no-build-isolation", "-w", str(wheel_dir), str(ROOT)],
        check=True,
    )
    (wheel,) = wheel_dir.glob("forcelearn-*.whl")
    subprocess.run([*pip, "install", "--no-deps", "--target", str(target), str(wheel)], check=True)
    probe = textwrap.dedent(
        f"""
        import sys
        sys.path = [{str(target)!r}] + [p for p in sys.path if not p.startswith({str(ROOT)!r})]
        import gymnasium
        env = gymnasium.make("forcelearn.envs:forcelearn/Contour-v0")  # imports the module
        obs, _ = env.reset(seed=0)
        env.step(env.action_space.sample())
        import forcelearn.envs
        assert forcelearn.envs.__file__.startswith({str(target)!r}), forcelearn.envs.__file__
        env = gymnasium.make("forcelearn/Surface-v0")
        obs, info = env.reset(seed=0)
        env.step(env.action_space.sample())
        env.close()
        print("made", type(env.unwrapped).__name__, round(info["start_force_n"], 3))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=False, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("made SurfaceEnv")
