"""
Seeing the simulation: MuJoCo's viewer window on the live world (:mod:`.window`). No ROS.

Front-ends of a :class:`~sim_node.session.Session`, like the node's publishers and the recorder:
they attach to what is loaded and never slow its physics.
"""
