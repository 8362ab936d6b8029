"""Speed benchmarks run by ``forcelearn bench NAME``: they print figures, never timed tests."""
