"""``python -m energy_margin``."""

import sys

from energy_margin.cli import main

__all__: list[str] = []

sys.exit(main())
