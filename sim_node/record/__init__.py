"""
Recording runs as rosbag2 bags (MCAP), that ros2 bag play and Foxglove open, without ROS.

:mod:`.bag` writes them on a thread of its own; :mod:`.session` records a session with no
rclpy; the node records what it publishes (``record`` parameter); :mod:`.replay` summarises
a bag, and :mod:`.playback` plays one back into the browser view.
"""
