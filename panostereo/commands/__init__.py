"""Subcommands of ``panostereo``; each module exposes ``configure(parser)`` and ``run(args) -> int``."""
