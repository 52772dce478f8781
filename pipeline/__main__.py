"""``python -m pipeline`` is the ``blobflow`` command."""

import sys

from .cli import main

sys.exit(main())
