"""Tele-operation: the FYD-pad finger drives a robot arm over ZeroMQ (Bianchi 2015, III-C, IV-B).

Master-side entry points (docs/teleop.md): ``teleop.master.run_session`` (stream to a
slave, get the docs/recording_format.md report), ``teleop.master.run_local_sim`` (the demo:
in-process simulated slave on a loopback socket). Imports only ``vision.state.FingerState``
from the project (docs/architecture.md).
"""
