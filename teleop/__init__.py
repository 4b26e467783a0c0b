"""Tele-operation: the FYD-pad finger drives a robot arm over ZeroMQ (paper 004, III-C, IV-B).

Master-side entry points (docs/teleop.md): ``teleop.master.run_session`` (stream to a
slave, get the RECORDING_FORMAT.md report), ``teleop.master.run_local_sim`` (the demo:
in-process simulated slave on a loopback socket). Imports only ``vision.state.FingerState``
from the project (DESIGN.md).
"""
