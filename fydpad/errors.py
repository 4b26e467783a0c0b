"""Errors the command line reports as one line, without a traceback."""

from __future__ import annotations


class UserError(Exception):
    """Bad input or a missing device: the message names the file, key, line or device."""
