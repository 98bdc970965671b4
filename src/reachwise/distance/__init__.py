"""reachwise.distance."""
