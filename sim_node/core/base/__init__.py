"""
The bottom layer of the core: what every folder above shares, importing none of them.

:mod:`.config` (the one configuration value), :mod:`.errors` (typed errors, one per Result
code), :mod:`.records` (immutable values: snapshots, states, entity records, the loop's
reports), :mod:`.checks` (input checks), :mod:`.quat` (quaternions: the one place rotations
are written), :mod:`.memory` (freed memory given back to the system), :mod:`.loads` (the
inertia a joint moves, read before a model compiles), :mod:`.surfaces` (a restitution as the
contact parameters that bounce so), :mod:`.native` (MuJoCo's calls that last, made through
ctypes so that the GIL goes meanwhile) and :mod:`.thread_warnings` (warnings caught on the
thread that raised them, and only there).
"""
