"""The import contracts (pyproject.toml, lint-imports) cover modules added later.

The tree's code is copied into a temporary folder, a module is added there,
and lint-imports runs on the copy alone (the installed tree is taken off
``sys.path``), so the test sees what CI would see after that change.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
CODE_FOLDERS = ("src", "drivers", "emulators", "tools")

RUN_ON_COPY = """
import sys
from importlinter.cli import lint_imports
copy, installed = sys.argv[1], sys.argv[2:]
sys.path[:] = [f"{copy}/{folder}" for folder in {folders!r}] + [
    entry for entry in sys.path if entry not in installed
]
sys.exit(lint_imports(config_filename=f"{copy}/pyproject.toml", no_cache=True, no_logo=True))
"""


def _contracts() -> dict[str, dict[str, Any]]:
    with (ROOT / "pyproject.toml").open("rb") as file:
        config = tomllib.load(file)
    return {c["id"]: c for c in config["tool"]["importlinter"]["contracts"]}


@pytest.fixture(scope="module")
def copy_of_the_tree(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """pyproject.toml and every .py file of the four code folders."""
    copy = tmp_path_factory.mktemp("tree")
    shutil.copy(ROOT / "pyproject.toml", copy)
    for folder in CODE_FOLDERS:
        shutil.copytree(ROOT / folder / "forcelearn", copy / folder / "forcelearn",
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return copy


def _lint_imports(copy: Path) -> subprocess.CompletedProcess[str]:
    installed = [str(ROOT / folder) for folder in CODE_FOLDERS]
    return subprocess.run(
        [sys.executable, "-c", RUN_ON_COPY.replace("{folders!r}", repr(CODE_FOLDERS)),
         str(copy), *installed],
        capture_output=True, text=True, timeout=120, check=False, cwd=copy,
    )


def test_a_module_outside_every_layer_fails_lint_imports(copy_of_the_tree: Path) -> None:
    """The copy passes as it is; one new module that no layer names breaks the layers."""
    before = _lint_imports(copy_of_the_tree)
    assert before.returncode == 0, before.stdout + before.stderr
    stray = copy_of_the_tree / "src" / "forcelearn" / "stray.py"
    stray.write_text('"""A module nobody placed in a layer."""\n')
    try:
        after = _lint_imports(copy_of_the_tree)
    finally:
        stray.unlink()
    assert after.returncode != 0
    assert "forcelearn.stray" in after.stdout, after.stdout
    assert "the layers, top to bottom; every module of forcelearn is in one BROKEN" in " ".join(
        after.stdout.split()
    )


def test_the_core_contract_names_exactly_the_core_layers() -> None:
    """The hardware-agnostic core is the layers between the public faces and the devices.

    The layers forbid every upward import; this contract forbids the core's
    downward ones into the drivers and emulators. It must name every module of
    those layers, so a core module placed there later is checked too.
    """
    contracts = _contracts()
    layers = [layer.split("#")[0].strip() for layer in contracts["layers"]["layers"]]
    top, bottom = layers.index("site"), layers.index("drivers | emulators")
    core = {f"forcelearn.{name.strip()}" for layer in layers[top + 1 : bottom]
            for name in layer.replace(":", "|").split("|")}
    forbidden = contracts["core-hardware-agnostic"]
    assert set(forbidden["source_modules"]) == core
    assert set(forbidden["forbidden_modules"]) == {"forcelearn.drivers", "forcelearn.emulators"}
