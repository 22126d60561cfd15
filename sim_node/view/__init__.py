"""
Seeing the simulation: MuJoCo's viewer window on the live world (:mod:`.window`). No ROS.

The browser view (:mod:`.web`, viser) shows the same for machines without a display;
:mod:`.source` is what both show (the session's world and its state, as its listener hears
them); :mod:`.xvfb` gives a window a virtual display where there is no screen.

Front-ends of a :class:`~sim_node.session.Session`, like the node's publishers and the recorder:
they attach to what is loaded and never slow its physics.
"""
