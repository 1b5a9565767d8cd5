"""``python -m user_agent ...`` = ``user-agent ...``."""

from __future__ import annotations

import sys

from user_agent.cli import main

sys.exit(main())
