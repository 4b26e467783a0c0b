"""Render chains for the station's fault tests, loaded by the render process by name."""

from __future__ import annotations

from pathlib import Path


class MarkerChain:
    """Records its ticks and writes ``safe_stop`` to a file when stopped safely."""

    outputs = ("vibration", "position")

    def __init__(self, spec):
        self.marker = Path(spec.motor_options["marker"])
        self.fail_after = spec.motor_options.get("fail_after_ticks")
        self.ticks = 0

    def tick(self, t_s, contact, x_mm, y_mm, speed_mm_s, force_n, vibration_gain,
             stiffness_n_per_mm):
        self.ticks += 1
        if self.fail_after is not None and self.ticks > self.fail_after:
            raise RuntimeError("injected actuator fault")
        return (0.1 * vibration_gain if contact else 0.0, 0.0)

    def safe_stop(self) -> None:
        self.marker.write_text(f"safe_stop after {self.ticks} ticks\n")
