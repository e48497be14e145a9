"""Values printed in Urrea & Pascal 2017, for the report to set side by side with ours.

These are the paper's numbers as published (Tables 4, 5 and 6), not a reference for the
physics: the truth of the simulated robot is ``Robot.paper().base_parameters()`` (Table 3
evaluated with Table 2; see the project's paper notes for the typos corrected there).
"""

from __future__ import annotations

#: Method keys of the study result, in the paper's order.
METHODS: tuple[str, ...] = ("least_squares", "adaline", "hopfield", "ekf")

#: Human-readable method names for tables and legends.
METHOD_LABELS: dict[str, str] = {
    "least_squares": "Least squares",
    "weighted_least_squares": "Weighted LS",
    "adaline": "Adaline",
    "hopfield": "Hopfield",
    "ekf": "EKF",
}

#: Table 4: the paper's estimates of λ1..λ8 per method (SI units, see PARAMETER_UNITS).
TABLE4: dict[str, tuple[float, ...]] = {
    "least_squares": (4.2969, 0.1094, 0.0677, 0.0671, 0.0271, 0.0260, 0.0251, 0.5114),
    "adaline": (4.2027, 0.1450, 0.0500, 0.0652, 0.0259, 0.0181, 0.0459, 0.6056),
    "hopfield": (4.2984, 0.0822, 0.0551, 0.0692, 0.0354, 0.0578, 0.0287, 0.5136),
    "ekf": (4.2966, 0.0647, -0.0114, -0.0080, 0.0742, 0.0634, 0.0859, 0.5119),
}

#: Table 5 as printed: every RMS ≤ this, every RSD ≤ this, every AI ≥ this.
TABLE5_MAX_RMS = 0.0012
TABLE5_MAX_RSD = 0.0112
TABLE5_MIN_AI = 0.9998

#: Table 6: the (min, max) of each λ_i in the paper's sensitivity sweep.
TABLE6_RANGES: tuple[tuple[float, float], ...] = (
    (2.1335, 6.4004),
    (0.0547, 0.1641),
    (0.0339, 0.1016),
    (0.0334, 0.1007),
    (0.0136, 0.0407),
    (0.0130, 0.0390),
    (0.0126, 0.0377),
    (0.2557, 0.7671),
)

#: Units of λ1..λ8: λ1 and λ8 are masses, λ2..λ7 moments of inertia.
PARAMETER_UNITS: tuple[str, ...] = ("kg",) + ("kg·m²",) * 6 + ("kg",)

#: Joint names and the units of their positions and generalised forces.
JOINTS: tuple[str, ...] = ("d1", "θ2", "θ3", "θ4", "d5")
FORCES: tuple[str, ...] = ("F1", "τ2", "τ3", "τ4", "F5")
POSITION_UNITS: tuple[str, ...] = ("m", "rad", "rad", "rad", "m")
FORCE_UNITS: tuple[str, ...] = ("N", "N·m", "N·m", "N·m", "N")
