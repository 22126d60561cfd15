"""
Advancing a world in time: the world lock, the live state it guards, the steps and the loop.

:mod:`.lock` (the world lock, fair enough that the loop steps aside for callers), :mod:`.live`
(the run phase's state: model, data, index, generation, commands and guard, behind that lock),
:mod:`.design` (the edit phase's state the live model was compiled from: the spec and its
tables, one immutable value that editing replaces),
:mod:`.steps` (the steps with the divergence check around them, and the loop's protocol),
:mod:`.guard` (divergence: MuJoCo's warnings and non-finite state, named and reported),
:mod:`.sampling` (declared sensors sampled at their own rates of simulated time as it steps),
:mod:`.odometers` (P3D plugins' ground truth among them), :mod:`.geo` (magnetometers and NavSat
receivers among them),
:mod:`.snapshots` (the newest snapshot, handed to every reader) and :mod:`.rate` (the
real-time factor the stepping thread achieves). The stepping thread itself reads the whole
world: :mod:`sim_node.core.loop`.
"""
