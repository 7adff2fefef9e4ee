"""``python -m energy_margin``."""

import sys

from energy_margin.cli import main

sys.exit(main())
