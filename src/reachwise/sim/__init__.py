"""reachwise.sim."""
