"""Exports of a pad session recording into other tools' formats (docs/ros.md)."""
