"""Tools around the controller: benchmarks, figure makers, the calibration tool."""
