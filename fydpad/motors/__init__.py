"""The two motors that stretch and vibrate the fabric (paper II-A, III-A, III-B eq. 3).

- :mod:`fydpad.motors.base`: the two-motor :class:`MotorPair` Protocol and ``MotorConfig``.
- :mod:`fydpad.motors.pwm`: eq. (3) composition with headroom and clip counts.
- :mod:`fydpad.motors.control`: the host position loop (input_POSITION) at 1 kHz.
- :mod:`fydpad.motors.drive`: one object per session: softness -> position, eq. 3 per tick.
- :mod:`fydpad.motors.sim`: the simulated fabric and motor plant (virtual clock).
- :mod:`fydpad.motors.qb`: the QB Robotics PSoC board over its serial packet protocol.
- :mod:`fydpad.motors.qb_emulator`: that board's emulator on a pseudo-terminal.
"""

from fydpad.motors.base import MotorConfig, MotorError, MotorPair

__all__ = ["MotorConfig", "MotorError", "MotorPair"]
