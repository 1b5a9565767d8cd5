"""The umbrella: the ``panostereo`` command and the site launcher.

This package sits above the three tiers: it may import any of them, and none
of them imports it.
"""

__version__ = "0.1.0"
