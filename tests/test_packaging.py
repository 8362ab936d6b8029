"""The distribution holds every code folder, and the console script answers."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import forcelearn.tools.cli

ROOT = Path(__file__).resolve().parents[1]
CODE_FOLDERS = ("src", "drivers", "emulators", "tools")


def _modules_in(folder: str) -> set[str]:
    """Return the wheel-relative paths of the Python files under a code folder."""
    base = ROOT / folder
    return {p.relative_to(base).as_posix() for p in base.rglob("*.py")}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Build the wheel once for this module."""
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "--quiet",
            "-w",
            str(out),
            str(ROOT),
        ],
        check=True,
    )
    (path,) = out.glob("forcelearn-*.whl")
    return path


@pytest.mark.parametrize("folder", CODE_FOLDERS)
def test_wheel_contains_every_module_of_each_code_folder(wheel: Path, folder: str) -> None:
    """A module missing from the wheel would be missing on every user's machine."""
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = _modules_in(folder)
    assert expected, f"{folder}/ holds no modules"
    missing = sorted(m for m in expected if m not in names)
    assert not missing, f"wheel lacks {missing}"


def test_wheel_declares_the_console_script(wheel: Path) -> None:
    """The `forcelearn` command is declared as an entry point of the wheel."""
    with zipfile.ZipFile(wheel) as zf:
        (entry,) = [n for n in zf.namelist() if n.endswith("entry_points.txt")]
        text = zf.read(entry).decode()
    assert "forcelearn = forcelearn.tools.cli:main" in text


def test_wheel_is_typed_and_declares_both_emulator_routes(wheel: Path) -> None:
    """py.typed (PEP 561), the forcelearn-jr3 can.interface entry point and the .pth hook."""
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        (entry,) = [n for n in names if n.endswith("entry_points.txt")]
        text = zf.read(entry).decode()
        hook = zf.read("forcelearn-serial-url.pth").decode()
    assert "forcelearn/py.typed" in names
    assert "[can.interface]" in text
    assert "forcelearn-jr3 = forcelearn.emulators.jr3.can_bus:Jr3EmulatorBus" in text
    assert "forcelearn/emulators/urlhandler/protocol_forcelearn-robot.py" in names
    assert hook.strip() == "import forcelearn.emulators.urlhandler.startup"


def test_every_module_imports() -> None:
    """No module is broken by a move (a study script nobody's test imports, say)."""
    code = (
        "import importlib, pkgutil, forcelearn\n"
        "skip = ('protocol_forcelearn-robot', '.startup', '.__main__')\n"
        "bad = []\n"
        "for m in pkgutil.walk_packages(forcelearn.__path__, 'forcelearn.'):\n"
        "    if m.name.endswith(skip):\n"
        "        continue\n"
        "    try:\n"
        "        importlib.import_module(m.name)\n"
        "    except Exception as exc:\n"
        "        bad.append(f'{m.name}: {exc!r}')\n"
        "print(bad)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, timeout=120)
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout


def test_version_flag_prints_the_installed_version(capsys: pytest.CaptureFixture[str]) -> None:
    """`forcelearn --version` prints the distribution version and exits 0."""
    with pytest.raises(SystemExit) as stop:
        forcelearn.tools.cli.main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"forcelearn {forcelearn.tools.cli.version()}"


def test_console_script_runs_in_a_subprocess() -> None:
    """The installed entry point resolves (catches a broken package assembly)."""
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, forcelearn.tools.cli; sys.exit(forcelearn.tools.cli.main(['--help']))",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "bench" in done.stdout


def test_only_the_chosen_subcommand_module_is_imported() -> None:
    """`--version` imports no command module; `sim ...` imports sim but not run's."""
    probe = (
        "import sys, forcelearn.tools.cli as c\n"
        "try:\n    c.main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in sys.modules if m.startswith('forcelearn.tools.')\n"
        "             and m != 'forcelearn.tools.cli'))"
    )
    version = subprocess.run(
        [sys.executable, "-c", probe, "--version"], capture_output=True, text=True, check=True
    )
    assert version.stdout.strip().splitlines()[-1] == "[]"
    helped = subprocess.run(
        [sys.executable, "-c", probe, "sim", "contour", "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    loaded = helped.stdout.strip().splitlines()[-1]
    assert "forcelearn.tools.commands.sim'" in loaded and "run_command" not in loaded


def test_wheel_ships_the_live_page(wheel: Path) -> None:
    """The live page's HTML, CSS and JavaScript are package data: no CDN, offline cell PCs."""
    names = set(zipfile.ZipFile(wheel).namelist())
    static = ROOT / "tools" / "forcelearn" / "tools" / "live" / "static"
    expected = {f"forcelearn/tools/live/static/{p.name}" for p in static.iterdir()}
    assert {"index.html", "live.js", "plot.js", "live.css"} <= {p.name for p in static.iterdir()}
    assert expected <= names, f"wheel lacks {sorted(expected - names)}"
