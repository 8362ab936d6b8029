"""The programs around the controller, one folder per role (docs/architecture.md).

``cli`` and ``commands`` (one module per ``forcelearn NAME``), ``experiments`` (the
engines: the §5 run, §4, calibration, the filter), ``study`` (the engine of
``forcelearn study``), ``results`` (each writes a docs/results page), ``figures``,
``benchmarks``, ``fuzz`` and ``live``. The library's front doors are
:mod:`forcelearn.site` (open a cell) and :mod:`forcelearn.envs` (Gymnasium).
"""
