"""The simulator: a world of walking people and camera robots, and the cameras that see it.

It stands in for what real data cannot give (panoramic lenses, robots that see each other, PTZ
heads, faults on demand), down to the pixels: the sensor node sees only what the renderers draw.

* the world, a pure function of (site, seed, goals, t): :mod:`~sim.world` (room, platforms,
  ground truth), :mod:`~sim.walkers` (people walking), :mod:`~sim.people` (their looks),
  :mod:`~sim.robots` (mobile platforms);
* the renderers, :mod:`sim.render`: panoramic (annular PAL) and PTZ pixels;
* the simulated source and PTZ head a sensor node reads and commands: :mod:`~sim.source`,
  :mod:`~sim.ptz_head`;
* the driver that turns the manager's view plans into robot goals: :mod:`~sim.driver`.

``sim`` imports only :mod:`common`; of the tiers, only the sensor node's source registry
(:mod:`sensor_node.build`) imports it, besides the ``panostereo`` tools, benchmarks and tests.
"""
