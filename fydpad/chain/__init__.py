"""The actuator chain (Felicetti 2022 sections 3.2-4.1): excite it, identify its
transfer function TF = CPSD_yx / PSD_x per stiffness setting, and pre-compensate the
texture vibration (offline Z = FIV / TF, live a minimum-phase FIR inverse).

Modules: ``excitation`` (band-limited random drive), ``estimate`` (Welch TF and
coherence, the checks), ``measure`` (driving a motor drive and reading the fabric
accelerometer), ``tf_file`` (the TF set on disk), ``compensate`` (offline eqs. 2-5 and
the regularised inverse), ``inverse_filter`` (the live causal inverse), ``plots``.
"""

from __future__ import annotations

from fydpad.errors import UserError


class ChainError(UserError):
    """The chain cannot be identified or compensated; the message says what to check."""
