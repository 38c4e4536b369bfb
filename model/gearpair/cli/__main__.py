"""``python -m gearpair.cli``: the same as the ``gearpair`` console script."""

import sys

from . import main

sys.exit(main())
