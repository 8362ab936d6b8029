"""The engines the commands drive: the §5 run, §4 contour, calibration and the force filter."""
