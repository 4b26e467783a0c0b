"""The station's web view (live image, plots, setup) and the identification experiment."""

from fydpad.web.server import WebServer, parse_web_address, start_web

__all__ = ["WebServer", "parse_web_address", "start_web"]
