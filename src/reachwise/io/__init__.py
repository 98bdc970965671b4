"""File formats: robot files (YAML, URDF), task, cloud and scenario data; one atomic
writer (:mod:`reachwise.io.atomic`) for them and for the design outputs of
:mod:`reachwise.results`."""
