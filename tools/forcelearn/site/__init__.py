"""Open a cell as its config says: the library's front door.

What ``can.Bus`` is to python-can and ``gymnasium.make`` to Gymnasium.
"""
