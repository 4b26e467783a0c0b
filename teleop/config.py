"""Tele-operation configuration: plain dataclasses whose defaults are the paper's values.

The project's config loader builds them from TOML sections; only numbers, strings,
tuples and lists here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: The sections of the one device file (`fydpad config show`) that belong to the other
#: packages: `teleop slave --config` skips them by name, so the slave reads the same file
#: as the station. Kept equal to the station's sections by a test, without teleop
#: importing fydpad.
OTHER_SECTIONS = ("camera", "tracker", "ir", "force", "softness", "motors", "pwm", "qb",
                  "loops", "endpoints", "accel")


@dataclass
class LinkConfig:
    """Where the slave listens and how the link is secured (docs/protocol.md)."""

    endpoint: str = "tcp://127.0.0.1:5555"
    curve: str = "auto"  # "auto": on unless the endpoint is loopback; "on"; "off"
    keys_dir: str = "teleop_keys"  # written by `teleop keys generate DIR`
    send_hwm: int = 100  # 0.1 s at 1 kHz: rides out a scheduler stall; the slave drops stale ones
    # SCHED_FIFO priority each end asks for while it runs (`teleop slave`, the master's
    # session, the demo; 0: normal scheduling). Refused without the right to it: the
    # process then runs on at normal priority and says so (teleop/realtime.py).
    rt_priority: int = 50

    def __post_init__(self) -> None:
        check_rt_priority(self.rt_priority)


def check_rt_priority(value: object) -> None:
    """ValueError naming ``link.rt_priority`` unless it is 0 (off) or 1-99."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 99:
        raise ValueError(f"link.rt_priority must be 0 (normal scheduling) or a SCHED_FIFO "
                         f"priority 1-99, got {value!r}")


@dataclass
class SafetyConfig:
    """Slave-side limits. Box in the robot base frame, mm."""

    box_min_mm: tuple[float, float, float] = (400.0, -150.0, 150.0)
    box_max_mm: tuple[float, float, float] = (700.0, 150.0, 400.0)
    max_speed_mm_s: float = 300.0  # a 100 mm/s tap passes with margin
    max_accel_mm_s2: float = 10000.0  # about 1 g: a 100 mm/s, 8 mm tap needs 2.5 m/s^2
    resume_speed_mm_s: float = 60.0  # after clutch or watchdog, glide back at this speed
    resume_done_mm: float = 0.2  # until within this distance of the target (then no speed step)
    reengage_jump_mm: float = 2.0  # a touch this far from the held x, y glides there,
    # at this speed (the acceleration limit and no-overshoot braking apply): the speed
    # limit, since the finger put itself there (on taps at random places 60 mm/s cost
    # 1-6 mm of x, y MAE, 150 mm/s 0.15-2.5 mm more than 300; docs/teleop.md)
    reengage_speed_mm_s: float = 300.0
    max_age_s: float = 0.2  # samples older than this (capture to arrival) are dropped
    watchdog_s: float = 0.25  # no valid sample this long -> hold; the arm is free to take
    # A capture time further ahead of the slave's estimate of the master's clock than this
    # is dropped as "future" (docs/protocol.md); so is a seq more than max_seq_step ahead.
    future_tolerance_s: float = 0.05
    max_seq_step: int = 10_000  # 10 s at 1 kHz: far more than a watchdog period's samples
    clock_window: int = 64  # samples per master in its clock-offset estimate
    # An operator hold longer than this stops the robot (UR: servoStop, stopScript); the
    # slave keeps answering with status "stopped" until restarted. 0: never.
    operator_hold_stop_s: float = 30.0


@dataclass
class MappingConfig:
    """Workspace frame (mm, seen from above) -> robot base frame (mm), paper IV-B."""

    origin_mm: tuple[float, float, float] = (550.0, 0.0, 250.0)  # workspace centre, surface
    rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # surface orientation in the base
    reflect_x: bool = False  # mirror the workspace x axis (e.g. operator facing the robot)
    scale: float = 1.0  # 1:1 as in the paper
    z_scale: float = 1.0  # robot depth per mm of indentation


@dataclass
class PredictionConfig:
    """How the slave estimates the finger's position now (docs/teleop.md)."""

    enabled: bool = True
    window: int = 6  # samples in the polynomial fit of x, y
    window_z: int = 4  # of the indentation: short, a tap lasts ~10 frames
    degree: int = 2  # quadratic: follows tap turns
    max_horizon_s: float = 0.12  # never extrapolate further than this
    arm_lag_s: float = 0.0  # feed-forward of the arm's own lag; 0 = arm default
    # The indentation: "imm" (two constant-acceleration Kalman filters, docs/teleop.md) or
    # "poly" (the quadratic over window_z samples, as x and y).
    method_z: str = "imm"
    noise_z_mm: float = 0.5  # IR indentation noise per frame (bundled recordings: 0.3-0.5)
    # Models, calm to quick (jerk PSD, mm^2/s^5); per model the probability that the
    # motion keeps it from frame to frame (the calm one sticky: the IR noise is not a
    # press), and at the lifted sample each contact starts from (a touch-down is a press).
    jerk_psd_z: tuple[float, ...] = (3e3, 3e5, 3e8)
    mode_stay: tuple[float, ...] = (0.998, 0.98, 0.95)
    mode_start: tuple[float, ...] = (0.02, 0.08, 0.9)


@dataclass
class SlaveConfig:
    """The slave loop."""

    period_s: float = 0.002  # control tick; the sim steps 1 kHz physics inside
    robot: str = "sim"
    ur_host: str = "192.168.1.10"
    ur_lookahead_s: float = 0.05  # servoL lookahead_time, ur-rtde range 0.03-0.2
    ur_gain: float = 600.0  # servoL gain, ur-rtde range 100-2000
    ur_frequency_hz: float = 500.0  # e-Series controller rate
    sim_joint_speed_rad_s: float = 1.7  # LBR iiwa 7 R800 joint speed limits ~1.7-2.3 rad/s


@dataclass
class TeleopConfig:
    """Everything tele-operation reads."""

    link: LinkConfig = field(default_factory=LinkConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    mapping: MappingConfig = field(default_factory=MappingConfig)
    prediction: PredictionConfig = field(default_factory=PredictionConfig)
    slave: SlaveConfig = field(default_factory=SlaveConfig)
    baseline_rate_hz: float = 10.0  # the paper's master rate
