"""What the thesis reports for the experiments our built-ins stand in for, with where.

The reports put these next to our own figures ("thesis says / we measured"). The
thesis's figures themselves are not available as images; its tables and the numbers
its text states are. Source: Kivelä 2017 (the thesis text and its publications P-I,
P-II, P-III, P-V). The machines, drill plans and poses behind them are proprietary;
our built-ins (``sb60``, ``tunnel-87``, ``p2-man1`` … ``p2-man6``, the P-III/P-V
scenarios) are public stand-ins, so agreement is expected in kind (every point
reached, the ranking's shape, a baseline that collides and an avoiding run that does
not), not digit for digit.
"""

from __future__ import annotations

#: P-I Table 3: initial and optimized normalized design of one run
#: (parameter: (initial, optimized, changed %)).
P1_TABLE3: dict[str, tuple[float, float, float]] = {
    "a1": (0.3400, 0.8207, 48.07),
    "a2": (0.7100, 0.6376, -7.24),
    "d3": (0.6600, 0.7456, 8.56),
    "d4": (0.6250, 0.9929, 36.80),
    "a4": (0.4000, 0.3454, -5.46),
    "d6": (0.7400, 0.4287, -31.13),
    "d7": (0.6400, 0.6581, 1.81),
    "base.x": (0.7500, 0.3857, -36.43),
    "base.y": (0.5000, 0.3167, -18.33),
    "base.z": (0.6667, 0.7004, 3.38),
}

#: P-I Table 4: mean and standard deviation of the normalized design over 10 runs.
P1_TABLE4: dict[str, tuple[float, float]] = {
    "a1": (0.7539, 0.0909),
    "a2": (0.6900, 0.2135),
    "d3": (0.6581, 0.2464),
    "d4": (0.7637, 0.2652),
    "a4": (0.6289, 0.2848),
    "d6": (0.2029, 0.2100),
    "d7": (0.6234, 0.0898),
    "base.x": (0.3216, 0.1909),
    "base.y": (0.0922, 0.1156),
    "base.z": (0.5903, 0.1730),
}
P1_RUNS = 10
P1_POINTS = 87

#: P-II Table 2: GCI, KCI and their mean of the six optimized configurations
#: (``None``: "no solution").
P2_TABLE2: dict[str, tuple[float, float, float] | None] = {
    "p2-man1": (0.1043, 0.0744, 0.0894),
    "p2-man2": (0.1158, 0.0858, 0.1008),
    "p2-man3": (0.1059, 0.0652, 0.0856),
    "p2-man4": (0.1006, 0.0840, 0.0923),
    "p2-man5": (0.0741, 0.0058, 0.0400),
    "p2-man6": None,
}
P2_BEST = "p2-man2"

#: P-III §5, Fig. 3b: the conventional controller self-collides at this time (s).
P3_COLLISION_S = 2.16
#: P-III §5: parts that may collide, 1000 points each; mean distance time 8 ms.
P3_POINTS_PER_PART = 1000
P3_DISTANCE_MS = 8.0

#: P-V §IV–V: the scanned cloud (about 5500 points after 3 cm downsampling) and the
#: grabber cloud (1000 points from CAD).
P5_SCAN_POINTS = 5500
P5_GRABBER_POINTS = 1000

CAVEAT = (
    "The thesis's machines, drill plans and poses are proprietary; ours are public "
    "stand-ins, so agreement is expected in kind, not digit for digit."
)

SOURCES = {
    "P-I": "Kivelä 2017, Publication I (P-I), §4, Tables 3–4, Figs. 4–6",
    "P-II": "Kivelä 2017, Publication II (P-II), §5, Table 2",
    "P-III": "Kivelä 2017, Publication III (P-III), §5, Fig. 3",
    "P-V": "Kivelä 2017, Publication V (P-V), §IV–V, Figs. 3–5",
}
