"""Figure makers (PNG, matplotlib Agg): runs, probe, calibration, filter, step timeline."""
