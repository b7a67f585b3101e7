"""Every number the two papers report that this suite compares against, in one place.

* Kim, Park, Kwon, Han 2020 (TDCN), Table 4: normalised MSE of global joint positions per scenario
  and their average, short and long clips (Mixamo).
* Villegas, Ceylan, Hertzmann, Yang, Saito 2021 (contact-aware), Tables 1, 3, 5 and 6:
  interpenetration, vertex contact MSE, foot contact accuracy, global position MSE (Mixamo).

The evaluation modules (:mod:`.tdcn`, :mod:`.contact`) put these beside our measurements.
"""

from __future__ import annotations

__all__ = [
    "PAPER_TABLE4",
    "TABLE4_COLUMNS",
    "CONTACT_PAPER_METRICS",
    "PAPER_TABLE1",
    "PAPER_TABLE3",
    "PAPER_TABLE5",
    "PAPER_TABLE6",
]

# ----------------------------------------------------------------------------- Kim et al. 2020
#: Table 4 of Kim et al. 2020 (normalised MSE): short (1)-(4), avg, long (1)-(4), avg
PAPER_TABLE4: dict[str, tuple[float, ...]] = {
    "Baseline": (4.79, 1.22, 3.99, 18.31, 7.08, 26.14, 4.64, 8.38, 45.34, 21.12),
    "Baseline-dense": (4.45, 1.73, 3.85, 19.71, 7.44, 23.66, 4.75, 9.14, 35.37, 18.23),
    "Baseline-dilated": (7.92, 4.53, 7.63, 26.26, 11.59, 30.14, 9.41, 11.24, 49.43, 25.06),
    "Baseline-height": (2.72, 0.88, 3.29, 6.63, 3.38, 14.86, 2.65, 9.13, 14.89, 10.38),
    "ours": (2.21, 0.82, 2.70, 4.06, 2.45, 1.65, 0.78, 3.00, 4.49, 2.48),
    "A1": (1.58, 0.99, 3.00, 4.21, 2.45, 1.63, 0.80, 3.49, 6.33, 3.06),
    "A2": (3.74, 2.71, 3.71, 9.60, 4.94, 3.99, 2.80, 4.89, 13.14, 6.20),
    "A3": (6.90, 1.70, 5.26, 25.23, 9.77, 12.27, 2.25, 6.23, 51.66, 18.10),
    "A4": (2.31, 1.28, 3.70, 4.30, 2.90, 1.97, 1.24, 4.23, 5.31, 3.19),
    "A5": (1.65, 1.15, 2.86, 5.54, 2.80, 2.03, 0.83, 3.58, 8.39, 3.71),
}
#: the columns of :data:`PAPER_TABLE4` (and of our Table 4)
TABLE4_COLUMNS = tuple(
    f"{length} ({k})" if k != "avg" else f"{length} avg"
    for length in ("short", "long")
    for k in ("1", "2", "3", "4", "avg")
)

# ----------------------------------------------------------------------------- Villegas et al. 2021
#: the metrics of the contact tables, in the papers' column order
CONTACT_PAPER_METRICS = (
    "interpenetration",
    "vertex contact MSE",
    "foot contact accuracy",
    "global position MSE",
)
#: Villegas et al. 2021, Tables 1, 3, 5, 6 (interpenetration, vertex contact MSE, foot accuracy,
#: position MSE)
PAPER_TABLE1 = {
    "Ours": (0.81, 3.87, 0.97, 0.48),
    "Efull + IK": (1.19, 4.52, 0.82, 1.58),
    "SAN": (1.43, 5.26, 0.63, 0.82),
    "SAN + IK": (1.32, 5.78, 0.73, 0.74),
    "PMnet": (2.94, 23.11, 0.70, 3.67),
    "NKN": (3.20, 14.86, 0.71, 8.15),
}
PAPER_TABLE3 = {
    "Eskel": (1.67, 4.23, 0.71, 0.56),
    "Eskel+Efoot": (1.59, 4.21, 0.80, 0.66),
    "Eskel+Efoot+Eint w/o w": (0.35, 7.94, 0.82, 1.00),
    "Eskel+Efoot+Eint": (0.56, 6.79, 0.81, 0.97),
    "Efull": (1.18, 4.52, 0.76, 1.54),
    "Efull + ESO": (0.81, 3.87, 0.97, 0.48),
}
PAPER_TABLE5 = {
    "Ours": (0.49, 2.24, 0.98, 0.31),
    "Efull + IK": (0.82, 2.81, 0.81, 1.97),
    "SAN": (1.21, 4.50, 0.61, 1.23),
    "SAN + IK": (1.17, 4.22, 0.71, 1.13),
    "PMnet": (2.94, 18.31, 0.71, 4.38),
    "NKN": (2.11, 13.00, 0.72, 13.95),
}
PAPER_TABLE6 = {
    "Ours": (1.14, 5.50, 0.96, 0.65),
    "Efull + IK": (1.56, 6.24, 0.84, 1.19),
    "SAN": (1.66, 6.02, 0.64, 0.42),
    "SAN + IK": (1.48, 7.34, 0.74, 0.35),
    "PMnet": (4.01, 27.92, 0.70, 2.97),
    "NKN": (4.29, 16.72, 0.70, 2.34),
}
