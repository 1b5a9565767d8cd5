"""Serving users: track history and its log, and PTZ cameras shared among agents."""
