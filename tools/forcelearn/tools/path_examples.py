"""Write the path examples of examples/paths/ (docs/path.md): parts, taught paths, a RAPID module.

Every file is computed here from closed forms, so ``python -m
forcelearn.tools.path_examples --out examples/paths`` rewrites them byte for
byte, and ``--check`` says whether the committed ones are still what this
program writes.

=====================  ==============================================================
cylinder-arc.csv       27 poses over the top of a foam-covered cylinder, the tool
                       turning 50 deg about the cylinder's axis
cylinder-arc.mod       the same path as a RAPID module: robtargets in a wobjdata
sphere-arc.csv         25 poses along a great circle of a foam-covered sphere
heightmap.csv          heights (mm) on a 5 mm grid: a wave along x, a slope along y
heightmap-path.csv     33 poses along the wave, the tool normal to the foam
parts.toml             each part's geometry, the foam and the path it goes with
=====================  ==============================================================

Every path is taught on the foam's skin (the part's surface moved out by the
foam's thickness, 40 mm, the default sponge's), the tool's z axis pressing
into it, its x axis along the travel.
"""

from __future__ import annotations

import argparse
import filecmp
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from forcelearn.emulators.physics.part import Cylinder, Heightmap, Sphere, contact
from forcelearn.paths import Frame, TaughtPath, ToolData, format_rapid_module, resample_path
from forcelearn.paths.csv_file import format_path_csv

FOAM_MM = 40.0
CYLINDER = Cylinder(point_mm=(900.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0), radius_mm=110.0)
SPHERE = Sphere(centre_mm=(900.0, 0.0, -100.0), radius_mm=160.0)
GRID_ORIGIN_MM = (800.0, -60.0, 50.0)
GRID_SPACING_MM = 5.0
GRID_SIZE = (41, 25)
WAVE_AMPLITUDE_MM = 8.0
WAVE_LENGTH_MM = 200.0
CROSS_SLOPE = 0.05  # mm of height per mm along y
WOBJ = Frame((900.0, 0.0, 0.0), (0.707106781, 0.0, 0.0, 0.707106781))
"""The cylinder's fixture: on its axis, turned 90 deg about z (a work object a site teaches)."""
ROLLER = ToolData(True, Frame((0.0, 0.0, 150.0)), 0.9, (0.0, 0.0, 60.0))
"""The emulated cell's default tool (emulators/.../physics/tool.py): TCP at its contact point."""


def _poses(points: np.ndarray, normals: np.ndarray) -> TaughtPath:
    """Poses at ``points``: tool z against the outward ``normals``, tool x along the travel."""
    travel = np.gradient(points, axis=0)
    z = -normals / np.linalg.norm(normals, axis=1, keepdims=True)
    x = travel - np.einsum("ij,ij->i", travel, z)[:, None] * z
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    xyzw = Rotation.from_matrix(np.stack([x, y, z], axis=2)).as_quat()
    wxyz = np.where(xyzw[:, 3:] < 0, -xyzw, xyzw)[:, [3, 0, 1, 2]]
    return _rounded(TaughtPath(points, wxyz))


def _rounded(path: TaughtPath) -> TaughtPath:
    """Positions to 0.1 µm, quaternions to 9 decimals, named p10, p20, ... as a pendant does."""
    names = tuple(f"p{10 * (i + 1)}" for i in range(len(path)))
    return TaughtPath(np.round(path.positions_mm, 4), np.round(path.quaternions_wxyz, 9), names)


def cylinder_arc(points: int = 27, turn_deg: float = 50.0) -> TaughtPath:
    """Over the top of the cylinder, across its axis, turning ``turn_deg``."""
    angle = np.radians(np.linspace(-turn_deg / 2, turn_deg / 2, points))
    normals = np.column_stack([np.sin(angle), np.zeros(points), np.cos(angle)])
    skin = CYLINDER.radius_mm + FOAM_MM
    return _poses(np.asarray(CYLINDER.point_mm) + skin * normals, normals)


def sphere_arc(points: int = 25, span_deg: float = 40.0, heading_deg: float = 30.0) -> TaughtPath:
    """Along a great circle through the sphere's top, heading ``heading_deg`` from x."""
    angle = np.radians(np.linspace(-span_deg / 2, span_deg / 2, points))
    heading = np.radians(heading_deg)
    across = np.array([np.cos(heading), np.sin(heading), 0.0])
    normals = np.sin(angle)[:, None] * across + np.cos(angle)[:, None] * [0.0, 0.0, 1.0]
    skin = SPHERE.radius_mm + FOAM_MM
    return _poses(np.asarray(SPHERE.centre_mm) + skin * normals, normals)


def heights_mm() -> np.ndarray:
    """The height grid: a wave along u (x) and a slope along v (y), rounded to 0.1 µm."""
    u = np.arange(GRID_SIZE[0]) * GRID_SPACING_MM
    v = np.arange(GRID_SIZE[1]) * GRID_SPACING_MM
    wave = WAVE_AMPLITUDE_MM * np.sin(2 * np.pi * u / WAVE_LENGTH_MM)
    return np.asarray(np.round(wave[:, None] + CROSS_SLOPE * v[None, :], 4), dtype=float)


def heightmap_path(points: int = 33, dense: int = 321) -> TaughtPath:
    """Along the wave at mid-width, 20..180 mm into the grid, on the foam's skin.

    The skin is the part's surface moved out along its normal, so its steps
    stretch over crests and shrink in troughs: the skin is traced densely, then
    resampled to ``points`` poses evenly spaced along it.
    """
    origin = np.asarray(GRID_ORIGIN_MM)
    part = Heightmap(heights_mm(), GRID_ORIGIN_MM, GRID_SPACING_MM, interpolation="cubic")
    above = np.column_stack([np.linspace(20.0, 180.0, dense), np.full(dense, 60.0),
                             np.full(dense, 30.0)])
    on_part = contact(part, origin + above).surface_mm
    skin = contact(part, on_part, offset_mm=FOAM_MM)
    traced = TaughtPath(skin.surface_mm, _poses(skin.surface_mm, skin.normal).quaternions_wxyz)
    return _rounded(resample_path(traced, points))


def parts_toml() -> str:
    """The geometry of each example part, in the keys of ``[emulator.part]`` (part_table.py)."""
    def vec(values: tuple[float, ...]) -> str:
        return "[" + ", ".join(f"{v:g}" for v in values) + "]"

    return "\n".join([
        "# The parts of the path examples (python -m forcelearn.tools.path_examples writes this).",
        "# Keys of [emulator.part] (part_from_table); the *-cell.toml beside this file run them.",
        f"# Each part is covered by {FOAM_MM:g} mm of foam; the paths are taught on its skin.",
        "",
        "[cylinder]",
        'shape = "cylinder"', f"point_mm = {vec(CYLINDER.point_mm)}",
        f"axis = {vec(CYLINDER.axis)}", f"radius_mm = {CYLINDER.radius_mm:g}",
        f"concave = {str(CYLINDER.concave).lower()}", f"foam_thickness_mm = {FOAM_MM:g}",
        'path = "cylinder-arc.csv"  # or cylinder-arc.mod, PROC main', "",
        "[sphere]",
        'shape = "sphere"', f"centre_mm = {vec(SPHERE.centre_mm)}",
        f"radius_mm = {SPHERE.radius_mm:g}", f"foam_thickness_mm = {FOAM_MM:g}",
        'path = "sphere-arc.csv"', "",
        "[heightmap]",
        'shape = "heightmap"',
        f'file = "heightmap.csv"  # heights[i, j] at x = {GRID_SPACING_MM:g} i, '
        f'y = {GRID_SPACING_MM:g} j',
        f"origin_mm = {vec(GRID_ORIGIN_MM)}", f"spacing_mm = {GRID_SPACING_MM:g}",
        "normal = [0, 0, 1]", "u_axis = [1, 0, 0]",
        'interpolation = "cubic"', f"foam_thickness_mm = {FOAM_MM:g}",
        'path = "heightmap-path.csv"', "",
    ])


def write_examples(out: Path) -> list[Path]:
    """Write every example file into ``out``; return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    cylinder = cylinder_arc()
    heights = "\n".join(",".join(f"{v:g}" for v in row) for row in heights_mm())
    files = {
        "cylinder-arc.csv": format_path_csv(cylinder),
        "cylinder-arc.mod": format_rapid_module(cylinder, module="CylinderArc", wobj=WOBJ,
                                                wobj_name="wCylinder", tool=ROLLER, decimals=6),
        "sphere-arc.csv": format_path_csv(sphere_arc()),
        "heightmap.csv": "# heights in mm; row i at x = 5 i mm, column j at y = 5 j mm "
                         "from origin_mm (parts.toml)\n" + heights + "\n",
        "heightmap-path.csv": format_path_csv(heightmap_path()),
        "parts.toml": parts_toml(),
    }
    for name, text in files.items():
        (out / name).write_text(text, encoding="utf-8")
    return [out / name for name in files]


def main(argv: list[str] | None = None) -> int:
    """Write the examples, or check that the committed ones match."""
    parser = argparse.ArgumentParser(prog="python -m forcelearn.tools.path_examples",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--out", type=Path, default=Path("examples/paths"),
                        help="folder to write (default: examples/paths)")
    parser.add_argument("--check", action="store_true",
                        help="write to a temporary folder and compare with --out; exit 1 if any "
                             "file differs")
    args = parser.parse_args(argv)
    if not args.check:
        for path in write_examples(args.out):
            print(path)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        differ = [p.name for p in write_examples(Path(tmp))
                  if not (args.out / p.name).exists()
                  or not filecmp.cmp(p, args.out / p.name, shallow=False)]
    for name in differ:
        print(f"{args.out / name} differs from what this program writes", file=sys.stderr)
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main())
