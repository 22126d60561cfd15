"""
What drives a world's joints between steps: commands, torques, trajectories and mobile bases.

:mod:`.commands` (joint commands staged by any thread, applied by name before each step),
:mod:`.actuation` (joint torques through a joint's motor or ``qfrc_applied``),
:mod:`.trajectory` (joint trajectories in simulated time, as joint_trajectory_controller runs
them), :mod:`.runs` (the trajectories being followed, driven before every step),
:mod:`.bases` (which entities are differential-drive or holonomic bases, and their wheels),
:mod:`.drives` (a base's velocity command, tracked on its own motion; the bases driven),
:mod:`.wheels` (what a spawn gives a wheeled model: wheel actuators, rolling casters),
:mod:`.interfaces` (a gz_ros2_control robot's position interfaces, held by gz_ros2_control's
law; which of their servos hold),
:mod:`.odometry` (the one planar odometry: every base's pose from its wheels, a diff drive's
or a car's, or the ground truth), :mod:`.motion` (the world's control part: trajectories
started and cancelled, bases found and driven, pushes and gains, each under the world lock),
:mod:`.manager` (a robot's controllers as ros2_control's controller manager keeps them) with
:mod:`.controller_types` (each controller type's class: its parameter schema, what it needs
and claims), :mod:`.diff_drive` and :mod:`.steering` (diff_drive_controller's and the
steering controllers' kinematics), :mod:`.limits` (their speed and angle limits per update
period), :mod:`.laws` (the controllers' laws, run on the stepping side at their update rate of
simulated time) and :mod:`.gz_systems` (the laws of an SDF model's gz-sim systems).
"""
