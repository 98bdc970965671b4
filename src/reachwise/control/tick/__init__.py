"""The controller's compiled tick (numba), one concept per module: ``types`` (the typed
input groups and the ``TickDiagnostics`` result), ``task`` (primary task velocity),
``memory`` (the guard's remembered collision lines), ``points`` (avoidance points),
``joints`` (joint limits), ``solve`` (the damped pseudo-inverse with avoidance in the
null space), ``guard`` (the approach guard) and ``step`` (the tick itself). The law is
documented in ``reachwise.control.controller``."""
