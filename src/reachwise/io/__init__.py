"""File formats: robot files (YAML, URDF), task, cloud and scenario data, synthesis
outputs, the sweep store; one atomic writer (:mod:`reachwise.io.atomic`) for them all."""
