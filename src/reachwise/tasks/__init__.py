"""reachwise.tasks."""
