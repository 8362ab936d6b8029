"""The site's twin: fit the emulated cell to a run's records, and check the fit.

``hidden_cells`` draws emulated cells over stated ranges (the hidden truth the
fit is checked against); the fit and its report live beside it.
"""
