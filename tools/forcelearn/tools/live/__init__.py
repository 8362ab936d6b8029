"""The live page of a run: ``forcelearn run --live``, ``forcelearn sim contour --live``, ``view``.

=================  ==============================================================
``model``          what the page shows, as plain data (pure, thread-safe)
``journal``        ``live.ndjson`` in the run directory: every step and trial as a
                   JSON line, appended as the run goes; replayed and followed by ``view``
``publish``        the run's hooks: feed the model and the journal, never block
``server``         a read-only HTTP server (standard library): the page, its static
                   files, ``/api/state`` (JSON) and ``/api/events`` (server-sent events)
``browser``        the page in the system's headless Chromium, through Playwright
``screenshot``     ``python -m``: a run directory's page as a PNG (the README's figure)
``static/``        the page: HTML, CSS and the project's own canvas plots (no CDN)
=================  ==============================================================

The page is read-only: no request it can make changes the run or moves the robot.
See docs/live.md.
"""
