"""Programs that each write one docs/results page (``python -m forcelearn.tools.results.NAME``)."""
