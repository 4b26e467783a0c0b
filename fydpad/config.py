"""The one device configuration: dataclasses from every package, loaded from one TOML file.

Each section of the TOML file is one dataclass; defaults are the paper's values, so an
empty file (or none) gives the paper's device. An unknown key or a value of the wrong
type is an error naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fydpad.accel.config import AccelConfig
from fydpad.errors import UserError
from fydpad.motors.base import MotorConfig
from fydpad.motors.pwm import PwmConfig
from fydpad.motors.qb import QbBoardConfig
from fydpad.softness import SoftnessConfig
from teleop.config import TeleopConfig
from vision.config import ForceConfig, IRConfig
from vision.contact import TrackerConfig
from vision.sources import CameraConfig


@dataclass
class LoopRates:
    """Each loop at its own rate (paper section II): vision at the camera rate (the paper
    ran its tracker every 100 ms), IR and force at the sensor rate, rendering at 1 kHz,
    tele-operation at the vision rate."""

    #: At most this rate (`fydpad run --vision-hz`; 10 like the paper), frames in between
    #: dropped; a camera slower than this sets the rate.
    vision_hz: float = 30.0
    ir_hz: float = 100.0
    force_hz: float = 100.0
    render_hz: float = 1000.0


@dataclass
class Endpoints:
    """Network endpoints (ZeroMQ) of the station."""

    teleop: str = "tcp://127.0.0.1:5555"
    #: The IR + load-cell board, ``serial:PORT[@BAUD]`` (`fydpad run --sensors`); empty:
    #: the source's own (a replay's ir.csv/force.csv, the synthetic pad's).
    sensors: str = ""


@dataclass
class StationConfig:
    """The whole device: one TOML section per field."""

    camera: CameraConfig = field(default_factory=CameraConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    ir: IRConfig = field(default_factory=IRConfig)
    force: ForceConfig = field(default_factory=ForceConfig)
    softness: SoftnessConfig = field(default_factory=SoftnessConfig)
    motors: MotorConfig = field(default_factory=MotorConfig)
    pwm: PwmConfig = field(default_factory=PwmConfig)
    qb: QbBoardConfig = field(default_factory=QbBoardConfig)
    teleop: TeleopConfig = field(default_factory=TeleopConfig)
    loops: LoopRates = field(default_factory=LoopRates)
    endpoints: Endpoints = field(default_factory=Endpoints)
    accel: AccelConfig = field(default_factory=AccelConfig)


class ConfigError(UserError):
    """A configuration file has an unknown key or a value of the wrong type."""


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _convert(value: Any, tp: Any, where: str) -> Any:
    """Check ``value`` (decoded TOML) against the annotation ``tp`` and convert it."""
    origin = typing.get_origin(tp)
    if origin in (types.UnionType, typing.Union):
        options = [a for a in typing.get_args(tp) if a is not type(None)]
        errors = []
        for option in options:
            try:
                return _convert(value, option, where)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{where}: wrong type {value!r}")
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table, got {value!r}")
        return _build(tp, value, where)
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, list):
            raise ConfigError(f"{where}: expected an array, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{where}: expected an array of {len(args)} values, got {value!r}")
        return tuple(_convert(v, a, f"{where}[{i}]") for i, (v, a) in enumerate(zip(value, args,
                                                                                  strict=True)))
    if origin is list:
        (arg,) = typing.get_args(tp)
        if not isinstance(value, list):
            raise ConfigError(f"{where}: expected an array, got {value!r}")
        return [_convert(v, arg, f"{where}[{i}]") for i, v in enumerate(value)]
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{where}: expected a finite number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{where}: unsupported type {_type_name(tp)}")


def _build(cls: Any, data: dict[str, Any], where: str) -> Any:
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in data.items():
        key_where = f"{where}.{key}" if where else key
        if key not in names:
            known = ", ".join(sorted(names))
            raise ConfigError(f"unknown key '{key_where}' (known keys here: {known})")
        kwargs[key] = _convert(value, hints[key], key_where)
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{where or 'config'}: {exc}") from None


def config_from_dict(data: dict[str, Any], source: str = "<config>") -> StationConfig:
    """Build the configuration from decoded TOML; errors are prefixed with ``source``."""
    try:
        return _build(StationConfig, data, "")
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None


def load_config(path: str | Path | None = None) -> StationConfig:
    """The effective configuration: the paper's defaults overridden by the TOML file."""
    if path is None:
        return StationConfig()
    path = Path(path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such configuration file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    return config_from_dict(data, str(path))


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value):
        return {
            f.name: _plain(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if getattr(value, f.name) is not None
        }
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    return value


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, allow_nan=False)  # a JSON string is a valid TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_table(name: str, table: dict[str, Any], out: list[str]) -> None:
    scalars = {k: v for k, v in table.items() if not isinstance(v, dict)}
    if scalars or not table:
        out.append(f"[{name}]")
        out.extend(f"{k} = {_toml_value(v)}" for k, v in scalars.items())
        out.append("")
    for k, v in table.items():
        if isinstance(v, dict):
            _toml_table(f"{name}.{k}", v, out)


def config_to_toml(config: StationConfig) -> str:
    """The configuration as TOML, one line per value; unset optional values are left out."""
    out: list[str] = []
    for name, table in _plain(config).items():
        _toml_table(name, table, out)
    return "\n".join(out)


def save_config(config: StationConfig, path: str | Path) -> None:
    Path(path).write_text(config_to_toml(config), encoding="utf-8")
