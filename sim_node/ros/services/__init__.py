"""
The node's services.

The node's services: :mod:`.services` (every simulation_interfaces service and the
simulate_steps action: each converts the request, asks the session or the world, converts the
answer; core errors become the standard's Result codes in one table) and :mod:`.worlds` (the
world services: MJCF and SDF worlds read, checked, built and swapped in).
"""
