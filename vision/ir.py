"""Sharp GP2Y0A41SK0F IR distance sensor: voltage <-> distance, paper eq. (1).

Eq. (1) of the FYD-pad paper is a 5th-order fit of distance against output voltage
(R^2 = 0.9987). Its result is in **centimetres** although the paper's text says
millimetres: at 1.25 V it gives about 10.5, which matches the sensor's datasheet
curve at 10.5 cm. The fit is valid from about 0.42 V (30 cm) to 2.75 V (4 cm);
outside that range it is not extrapolated. Between about 2.2 V and 2.5 V the curve
is nearly flat, so distances there (roughly 5-6 cm) are resolved poorly.

Voltage to distance, per sensor, is :func:`vision.indentation.sensor_distances_mm`;
this module holds the curve and its inverse (the simulated sensors' output).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Eq. (1) coefficients, highest power first (np.polyval order); result in cm.
PAPER_POLY_CM: tuple[float, ...] = (-4.6327, 39.954, -133.8297, 220.8604, -188.5623, 79.0712)
#: The range of voltages over which eq. (1) is valid (30 cm to 4 cm).
VALID_VOLTAGE_RANGE_V: tuple[float, float] = (0.42, 2.75)
#: The sensor's own measurement period (datasheet: 16.5 +- 3.7 ms): it measures that
#: often and holds its output in between, whatever the rate the board reads it at.
SENSOR_PERIOD_S = 0.0165


def distance_to_voltage_v(
    distance_mm: ArrayLike,
    poly_cm: ArrayLike = PAPER_POLY_CM,
    valid_range_v: tuple[float, float] = VALID_VOLTAGE_RANGE_V,
    table_size: int = 4096,
) -> NDArray[np.float64]:
    """Inverse of eq. (1) over its valid range, by interpolation on a dense table.

    Eq. (1) is monotonically decreasing over the valid range, so the inverse is unique.
    Distances beyond the range saturate at its ends, as the real sensor's output does.
    """
    v_table = np.linspace(valid_range_v[0], valid_range_v[1], table_size)
    d_table_mm = np.polyval(np.asarray(poly_cm, dtype=np.float64), v_table) * 10.0
    # np.interp wants increasing x: distances decrease with voltage, so reverse.
    return np.interp(np.asarray(distance_mm, dtype=np.float64), d_table_mm[::-1], v_table[::-1])
