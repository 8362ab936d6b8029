"""Deprecated: ``python -m forcelearn.emulators.computer_link`` (this name warns, then runs it)."""

import sys

from forcelearn.emulators.computer_link.__main__ import main

if __name__ == "__main__":
    sys.exit(main())
