"""Every ``python -m`` program of forcelearn answers ``--help`` with its usage and exit 0.

The programs are found by walking the package's folders (every ``__main__.py``
and every module with an ``if __name__ == "__main__":`` block), not from a
list. Each runs in this process as ``python -m`` runs it (``runpy`` with
``__main__`` as its name and ``sys.argv`` set), which shares the imports
between programs and keeps the test to a few seconds; one program also runs
in a real ``python -m`` subprocess, so the command line itself is covered.
"""

from __future__ import annotations

import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

import forcelearn

MAIN_BLOCK = re.compile(r"""^if __name__ == ["']__main__["']:""", re.MULTILINE)


def python_m_programs() -> list[str]:
    """The module names ``python -m`` can run, over every folder of the namespace package."""
    names: set[str] = set()
    for root in map(Path, forcelearn.__path__):
        for path in root.rglob("*.py"):
            parts = ("forcelearn", *path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__main__":
                names.add(".".join(parts[:-1]))
            elif MAIN_BLOCK.search(path.read_text(encoding="utf-8")):
                names.add(".".join(parts))
    return sorted(names)


PROGRAMS = python_m_programs()


def test_the_walk_finds_the_known_programs() -> None:
    """The walk sees both kinds: a package's ``__main__.py`` and a module's main block."""
    assert {"forcelearn.emulators.egm", "forcelearn.tools.fuzz", "forcelearn.tools.cli"} <= set(
        PROGRAMS
    )


# In one process a module that an earlier program imported is in sys.modules already, which
# runpy notes with a RuntimeWarning; a fresh ``python -m`` never has it imported before.
@pytest.mark.filterwarnings("ignore:.*found in sys.modules after import of package:RuntimeWarning")
@pytest.mark.parametrize("program", PROGRAMS)
def test_a_program_answers_help(
    program: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``python -m PROGRAM --help`` prints its usage and exits 0."""
    monkeypatch.setattr(sys, "argv", [program, "--help"])
    with pytest.raises(SystemExit) as exit_info:
        runpy.run_module(program, run_name="__main__", alter_sys=True)
    assert exit_info.value.code in (0, None)
    assert "usage:" in capsys.readouterr().out


def test_python_m_runs_a_program_from_the_command_line() -> None:
    """The command line itself: a real interpreter, ``-m``, ``--help``."""
    result = subprocess.run(
        [sys.executable, "-m", "forcelearn.emulators.computer_link", "--help"],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert result.returncode == 0 and "usage:" in result.stdout, result.stderr
