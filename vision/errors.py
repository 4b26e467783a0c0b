"""The project's one error tree; every package may import it (``vision`` imports nothing).

::

    FydpadError                  anything this project raises on purpose
    +-- UserError                bad input (a file, key, line, option): one line, exit 2
    +-- DeviceFault              a device or peer failed: the station takes its fail-safe
                                 path (vibration off, motors at rest, robot holding)

Each package's own errors derive from one of the two (``vision.recording.RecordingError``
from ``UserError``, ``fydpad.motors.base.MotorError`` from ``DeviceFault``, ...), keeping
the built-in base they had (``ValueError``, ``RuntimeError``) so existing handlers still
catch them. The ``fydpad`` and ``teleop`` commands print any ``FydpadError`` as one line.
"""

from __future__ import annotations


class FydpadError(Exception):
    """The root of every error the project raises on purpose."""


class UserError(FydpadError):
    """Bad input or a missing device: the message names the file, key, line or device."""


class DeviceFault(FydpadError):
    """A device, or a peer on a link, failed or sent what it must not.

    ``str()`` names the device (class attribute ``device``, or ``device=``) unless the
    message already does, and says what to check (``check``) unless the message already
    does.
    """

    device: str = "device"
    check: str = ""

    def __init__(self, *args: object, device: str | None = None, check: str | None = None):
        super().__init__(*args)
        if device is not None:
            self.device = device
        if check is not None:
            self.check = check

    def __str__(self) -> str:
        text = super().__str__()
        low = text.lower()
        if self.device.lower() not in low:
            text = f"{self.device}: {text}" if text else self.device
        if self.check and "check" not in low and "?" not in text:
            text = f"{text}; check {self.check}"
        return text
