"""
Changing what a world is made of while it runs, all or nothing, and writing its state.

:mod:`.editor` (the MjSpec edits themselves), :mod:`.edits` (each structural edit and physics
parameter, planned against the live world), :mod:`.transaction` (the one commit path: plan
under the lock, build outside it, commit), :mod:`.transfer` (the live state carried to a new
model by element names), :mod:`.writes` (entity poses and twists, joint positions and
velocities written between steps). The design an edit replaces is
:mod:`sim_node.core.stepping.design`.
"""
