"""
The node's own command inputs.

The node's own command inputs, for entities without ros2_control: :mod:`.command_drain`
(``joint_commands``, taken in batches, the newest per joint), :mod:`.trajectories`
(FollowJointTrajectory for every entity with joints) and :mod:`.bases` (mobile bases:
``<entity>/cmd_vel`` in, ``<entity>/odom`` and the odom TF out).
"""
