"""
Quality of service of the simulation services, for the node and for clients.

Every client of a service reads the one reply topic of that service: each reply goes to every
client's reader, and the client library drops the ones meant for others. With ROS's default
service depth of 10, a burst of replies to other clients pushes a client's own reply out of
its reader's history before it is taken: with both cores busy, 50 clients calling at once got
36 to 41 answers (the node had served every request); with depth 100, all 50 in each of six
bursts. The node keeps 1,000 requests the same way (at depth 10 it lost most of a burst's
requests).
Clients that may call together with many others should use :data:`SERVICE_QOS` too.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

SERVICE_QOS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE)

#: Latched topics (/tf_static, markers, robot descriptions, the instance announcement): the
#: last message reaches a subscriber that comes later, as robot_state_publisher offers it.
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)

#: simulate_steps feedback: one message per step (the standard), sent in bursts after each chunk
#: of steps. A reader at ROS's default depth of 10 (``ros2 action send_goal``) keeps only the
#: newest of a burst; a client that wants every message subscribes with this depth
#: (:class:`~sim_node.ros.client.SimClient` does).
FEEDBACK_QOS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE)
