"""The web server's small pure pieces (the browser tests cover the rest)."""

from __future__ import annotations

import pytest

from fydpad.web.server import is_loopback, parse_web_address


def test_parse_web_address():
    assert parse_web_address("8080") == ("127.0.0.1", 8080)
    assert parse_web_address(":8080") == ("127.0.0.1", 8080)
    assert parse_web_address("0.0.0.0:0") == ("0.0.0.0", 0)
    assert parse_web_address("[::1]:9000") == ("::1", 9000)
    for bad in ("x", "host:", "1:99999"):
        with pytest.raises(ValueError, match="--web"):
            parse_web_address(bad)


def test_loopback():
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
    assert not is_loopback("pad.local")
