"""reachwise.viz."""
