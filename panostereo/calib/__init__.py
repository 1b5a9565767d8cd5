"""Calibrating a site from the people it sees (``panostereo calib refine``).

Stages, each a module: :mod:`.observe` (a site's detection files or a recording's Features -> every camera's
foot and head rays in its own frame), :mod:`.poses` (a camera's pose and its parameters), :mod:`.associate`
(which rays of one instant are one person, with the current poses), :mod:`.search` (a camera far from its
guess found again against the cameras already trusted), :mod:`.adjust` (the bundle adjustment), :mod:`.refine`
(the whole refinement and its report) and :mod:`.site_out` (the refined site written out).
"""
