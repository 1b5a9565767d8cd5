"""Benchmarks: each ``bench_*.py`` runs as ``python -m benchmarks.<name>`` and prints one JSON object.

``python -m benchmarks.run_all`` (``make bench``) runs them all. Timing goals live here, never in tests.
"""
