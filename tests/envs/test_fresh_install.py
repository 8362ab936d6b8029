"""What the wheel registers works from a fresh install, not from the source tree.

``gymnasium.make("forcelearn/...")``, ``can.Bus(interface="forcelearn-jr3")`` (a
``can.interface`` entry point) and ``serial.serial_for_url("forcelearn-robot://")``
(the wheel's ``.pth`` hook).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def target(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel, built and installed into an empty folder (once for this module)."""
    tmp = tmp_path_factory.mktemp("fresh")
    wheel_dir, site_dir = tmp / "wheel", tmp / "site"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--quiet"]
    subprocess.run(
        [*pip, "wheel", "--no-deps", "--no-build-isolation", "-w", str(wheel_dir), str(ROOT)],
        check=True,
    )
    (wheel,) = wheel_dir.glob("forcelearn-*.whl")
    subprocess.run([*pip, "install", "--no-deps", "--target", str(site_dir), str(wheel)],
                   check=True)
    return site_dir


def _isolated(target: Path) -> str:
    """Code that makes the subprocess import forcelearn from ``target`` only.

    The editable install's source folders leave ``sys.path``; ``target`` is
    added as a site folder, so its ``.pth`` hooks run as in a real environment,
    and put first, ahead of a copy installed in the venv.
    """
    return textwrap.dedent(
        f"""
        import site, sys
        sys.path = [p for p in sys.path  # the source folders, not a venv named like the tree
                    if p != {str(ROOT)!r} and not p.startswith({str(ROOT) + "/"!r})]
        sys.path.insert(0, {str(target)!r})  # ahead of a copy installed in the venv
        for name in [m for m in sys.modules if m == "forcelearn" or m.startswith("forcelearn.")]:
            del sys.modules[name]  # imported at start-up by an installed copy's .pth hook
        site.addsitedir({str(target)!r})  # runs the target's .pth hooks
        """
    )


def test_gymnasium_make_works_from_a_fresh_install_of_the_wheel(
    target: Path, tmp_path: Path
) -> None:
    """Make both envs from the installed wheel only."""
    probe = _isolated(target) + textwrap.dedent(
        f"""
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


def test_both_emulator_routes_open_from_a_fresh_install(target: Path, tmp_path: Path) -> None:
    """python-can finds ``forcelearn-jr3`` and pyserial ``forcelearn-robot://`` with no import."""
    probe = _isolated(target) + textwrap.dedent(
        f"""
        import can, serial
        bus = can.Bus(interface="forcelearn-jr3", channel="fresh")
        bus.send(can.Message(arbitration_id=0x401, data=b"", is_extended_id=False))  # get_state
        # the answer: ACK (0x100) of node 1
        reply = bus.recv(1.0)
        bus.shutdown()
        port = serial.serial_for_url("forcelearn-robot://?instant=1", timeout=1.0)
        module = type(port).__module__
        port.close()
        import forcelearn.emulators
        assert forcelearn.emulators.__file__.startswith({str(target)!r})
        print("routes", hex(reply.arbitration_id), module)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=False, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == [
        "routes", "0x101", "forcelearn.emulators.computer_link.serial_port"
    ]
