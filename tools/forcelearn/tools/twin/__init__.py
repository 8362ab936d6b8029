"""The site's twin (issue 29): fit the emulated cell to a run's records, and replay a run on it."""
