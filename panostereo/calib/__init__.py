"""Calibrating a site from the people it sees (``panostereo calib refine``).

Stages, each a module: :mod:`.observe` (a site's detection files or a recording's Features -> every camera's
foot and head rays in its own frame), :mod:`.poses` (a camera's pose and its parameters), :mod:`.associate`
(which rays of one instant are one person, with the current poses), :mod:`.search` (a camera far from its
guess found again against the cameras already trusted), :mod:`.adjust` (the bundle adjustment), :mod:`.refine`
(the whole refinement and its report) and :mod:`.site_out` (the refined site written out).
"""

DEFAULT_INSTANTS = 1000
"""Instants ``calib refine`` uses unless told (evenly spread over the data): a few minutes of a busy site at any
frame rate. The adjustment uses at most 5000 person-instants anyway; more instants only lengthen the association
(about two seconds a round for a crowd of 20 seen by seven cameras at 400)."""
