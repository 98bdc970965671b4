"""reachwise.control."""
