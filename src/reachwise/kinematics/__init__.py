"""reachwise.kinematics."""
