"""reachwise.io."""
