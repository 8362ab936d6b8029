"""``python -m forcelearn.tools.fuzz [TARGET ...]``: the fuzz harness (docs/fuzzing.md)."""

import sys

from forcelearn.tools.fuzz.targets import main

sys.exit(main())
