"""The gear pair as a scipy user would write it: `gearpair.bench.plain_scipy` (it ships with
the package, so that an installed ``gearpair bench`` has its rows). This entry point runs its
comparison with the fast engine, as ``python -m gearpair.bench.plain_scipy`` does::

    python benchmarks/plain_scipy.py [--t-end 0.02] [--rtol 1e-9] [--method DOP853]
        [--stiffness rectangular] [--friction stick_slip] [--torque 3900] [--rpm 100]
"""

from __future__ import annotations

import sys

from gearpair.bench.plain_scipy import main

if __name__ == "__main__":
    sys.exit(main())
