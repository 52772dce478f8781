"""``python -m pipeline`` is the ``blobflow`` command."""

import sys

from .cli.app import main

if __name__ == "__main__":  # not again in the processes that multiprocessing spawns
    sys.exit(main())
