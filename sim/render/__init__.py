"""Rendering the simulated world into a camera's pixels.

:mod:`~sim.render.cameras` (the renderers: panoramic and PTZ, light and noise) composes
:mod:`~sim.render.room` (the room's textures, cast per column), :mod:`~sim.render.bodies`
(people and platforms as primitives), :mod:`~sim.render.panoramic` and :mod:`~sim.render.ptz`
(painting the primitives into a panorama or along a PTZ camera's rays) and
:mod:`~sim.render.extras` (cast shadows, a swaying plant).
"""
