"""
What a model carries that looks at the world: sensor groups, contacts, the renderer.

:mod:`.catalog` (a model's cameras, sites and sensor groups), :mod:`.rendering` (the headless
OpenGL backend and renderer), :mod:`.contacts` (what touches what, as a contact sensor reports
it). The camera rigs and laser scanners, which read a whole world through its facade, sit
above it: :mod:`sim_node.core.cameras`, :mod:`sim_node.core.lidar`.
"""
