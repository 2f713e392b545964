"""Seed 002's worked examples: Table 1 (cable lengths) and Table 2 (pose and tensions).

The tables print three decimals; comparisons allow one unit of the last digit, since
some entries are rounded and others cut off. Example 3's tau_2 is a misprint: with
cables 1 and 2 vertical and taut, tau_1 + tau_2 = mg = 98 kN and the moment balance
about the centre of gravity gives tau_1 (1 - k1) a = tau_2 (1 + k1) a, so
tau_2 = 36.750 kN, not the printed 38.750 (tau_1 = 61.250 kN is printed correctly).
"""
from __future__ import annotations

TABLE_1 = {
    1: (20.0, 21.0, 22.0, 21.5),
    2: (20.0, 20.0, 20.1, 20.1),
    3: (20.0, 20.0, 21.0, 21.0),
    4: (20.3, 20.1, 20.5, 20.2),
}

# Example 1: suspended by cable 1 alone, rotational range phi [rad].
EXAMPLE_1_RANGE = ((0.0, 0.715), (5.565, 6.28))

TABLE_2_ROWS = ("B1x", "B1y", "B1z", "B2x", "B2y", "B2z", "B3x", "B3y", "B3z", "Cx", "Cy", "Cz",
                "tau1_kN", "tau2_kN", "tau3_kN", "tau4_kN")
TABLE_2 = {
    2: (2.000, 2.499, -19.999, -2.000, 2.499, -19.999, -2.000, -2.499, -20.099, 0.500, 0.700, -30.038,
        39.201, 23.520, 13.229, 22.049),
    3: (2.000, 2.500, -20.000, -2.000, 2.500, -20.000, -2.000, -2.403, -20.981, 0.500, 2.500, -30.198,
        61.250, 38.750, 0.0, 0.0),
    4: (1.996, 2.499, -20.299, -1.999, 2.499, -20.099, -1.995, -2.499, -20.000, -0.001, 0.299, -30.170,
        5.856, 49.018, 0.0, 43.126),
}
TAUT_SETS = {2: (1, 2, 3, 4), 3: (1, 2), 4: (1, 2, 4)}
TABLE_2_TOLERANCE = 1e-3
MISPRINTS = {(3, "tau2_kN"): 36.750}


def physical_table2(example: int) -> tuple[float, ...]:
    """Table 2's column for an example with its misprints replaced by what equilibrium needs."""
    return tuple(MISPRINTS.get((example, row), value) for row, value in zip(TABLE_2_ROWS, TABLE_2[example]))
