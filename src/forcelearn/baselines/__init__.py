"""Baselines for the §5 task and a runner that scores every method by the same rule.

See :mod:`forcelearn.baselines.controllers` (srv, pi, ilc, cma),
:mod:`forcelearn.baselines.sac` (SAC, needs ``forcelearn[baselines]``) and
:mod:`forcelearn.baselines.runner` (recording and the budget rule).
"""
