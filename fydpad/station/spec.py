"""What the station's render process is asked to render: a picklable description, sent to
the process at its start (:mod:`fydpad.station.render`), from which it builds its chain
(:mod:`fydpad.station.chains`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from fydpad.station.row_log import DEFAULT_BUFFER_S


@dataclass
class RenderSpec:
    """Everything the render process needs to build its chain (picklable)."""

    rate_hz: float = 1000.0
    #: A texture model file (None: no vibration).
    texture: str | None = None
    #: More texture models, all loaded at start and selected live by the control record's
    #: ``texture_index`` (1, 2, ...; 0 is ``texture``): no file I/O in the 1 kHz loop.
    textures: tuple[str, ...] = ()
    vibration_gain: float = 1.0
    #: Band-pass LPC models' vibration through the model file's drive band (paper III-B:
    #: 165-220 Hz, where the fabric's actuator chain responds).
    drive_filter: bool = False
    stiffness_n_per_mm: float = math.nan
    #: "sim" (the simulated fabric and motor plant) or "qb" (the QB board) or "none".
    motors: str = "none"
    motor_options: dict = field(default_factory=dict)
    #: Write every tick's commands here (CSV), or None.
    commands_csv: str | None = None
    #: Seconds of commands-log rows buffered against a stalled disk (at ``rate_hz``).
    commands_buffer_s: float = DEFAULT_BUFFER_S
    #: Try SCHED_FIFO and a core of its own (needs the right to; falls back silently).
    realtime: bool = True
    #: A custom chain, "module:callable" taking the spec (labs' own actuators, tests).
    chain: str | None = None
    #: The device configuration (motor, PWM, board and softness sections are used).
    config: Any = None
    #: A TF file of ``fydpad chain identify``: its inverse pre-compensates the vibration.
    compensate: str | None = None
    #: Output channels, ``[SIGNAL=]TARGET[,fs=X]`` each (fydpad.station.outputs).
    channels: tuple[str, ...] = ()
    #: Ticks per block handed to the channels (10: 10 ms).
    channel_block_ticks: int = 10
