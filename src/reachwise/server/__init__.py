"""reachwise.server."""
