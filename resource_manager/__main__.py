"""``python -m resource_manager --config FILE``: same as ``resource-manager``."""

from __future__ import annotations

import sys

from resource_manager.cli import main

if __name__ == "__main__":
    sys.exit(main())
