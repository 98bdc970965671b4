"""Design outputs as files: a synthesis result's folder (``design.yaml``, ``design.urdf``,
``summary.json``, ``points.csv``), a Pareto front's files and the SQLite store of
topology sweeps. They sit above both :mod:`reachwise.io` (whose atomic writer and robot
file they use) and :mod:`reachwise.synthesis` (whose results they write), beside the
reports, so that reading a robot or task file never imports the synthesis."""
