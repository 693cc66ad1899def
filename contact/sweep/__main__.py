"""``python -m contact.sweep``: the sweep's command line (:func:`contact.sweep.command.main`)."""

from __future__ import annotations

import sys

from .command import main

if __name__ == "__main__":
    sys.exit(main())
