"""Shared by every tier: wire schema, keys, sessions, config, clock, camera models and geometry.

``common`` imports none of the tiers (``sensor_node``, ``resource_manager``,
``user_agent``) nor the umbrella ``panostereo`` package.
"""
