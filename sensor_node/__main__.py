"""``python -m sensor_node --config FILE``: same as ``sensor-node``."""

from __future__ import annotations

import sys

from sensor_node.cli import main

if __name__ == "__main__":
    sys.exit(main())
