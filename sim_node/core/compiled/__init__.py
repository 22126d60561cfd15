"""
One compiled model: what its names and addresses are, and its state read and written.

:mod:`.index` (names and addresses of one compiled model: entities, joints, actuators,
sensors; rebuilt with every generation) and :mod:`.state` (reading and writing the state of
one model and data by those addresses). Above :mod:`sim_node.core.models` and
:mod:`sim_node.core.devices`, whose tables the index reads; below control, stepping and editing.
"""
