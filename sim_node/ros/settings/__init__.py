"""
What every room of the ROS layer shares, below them all.

:mod:`.parameter_table` (every parameter of the node as one table, which also writes
docs/parameters.md), :mod:`.params` (declaring them from it and reading them back: the world's
configuration, frames, the perception settings), :mod:`.qos` (the services' quality of
service, shared with clients) and :mod:`.replies` (how every service's replies are delivered:
one the middleware could not send at once is sent again until the client can hear it).
"""
