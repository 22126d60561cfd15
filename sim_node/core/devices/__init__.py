"""
What a model carries that looks at the world: cameras, laser scanners, sensor groups, contacts.

:mod:`.catalog` (a model's cameras, sites and sensor groups), :mod:`.rendering` (the headless
OpenGL backend and renderer), :mod:`.cameras` (camera rigs, intrinsics, pictures),
:mod:`.lidar` (laser scanners by ray casting), :mod:`.contacts` (what touches what, as a
contact sensor reports it).
"""
