"""Taught paths: read from a CSV file or a RAPID module, checked, resampled (docs/path.md).

A :class:`TaughtPath` is an ordered list of poses in the robot's base frame
(position in mm, unit quaternion w, x, y, z), each with its name and the source
line it came from, so a refusal can point at the line a site engineer must fix.

=====================  ===================================================
:func:`read_path_csv`  ``x_mm,y_mm,z_mm,qw,qx,qy,qz`` rows
:func:`read_rapid`     robtargets, wobjdata, tooldata and the moves of a PROC
:func:`validate_path`  the refusals before any move (:class:`PathLimits`)
:func:`resample_path`  n points per pass: positions linear, orientations slerp
=====================  ===================================================
"""

from forcelearn.paths.csv_file import read_path_csv, write_path_csv
from forcelearn.paths.rapid_module import read_rapid, read_rapid_text
from forcelearn.paths.rapid_writer import format_rapid_module
from forcelearn.paths.resample import resample_path
from forcelearn.paths.taught import Frame, TaughtPath, ToolData
from forcelearn.paths.validation import QUATERNION_TOLERANCE, PathLimits, validate_path

__all__ = [
    "QUATERNION_TOLERANCE",
    "Frame",
    "PathLimits",
    "TaughtPath",
    "ToolData",
    "format_rapid_module",
    "read_path_csv",
    "read_rapid",
    "read_rapid_text",
    "resample_path",
    "validate_path",
    "write_path_csv",
]
