"""reachwise.synthesis."""
