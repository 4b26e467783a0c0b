"""The station's web view (live image, plots, setup) and the identification experiment.

The server is :mod:`fydpad.web.server` (aiohttp); this package's ``__init__`` imports
nothing, so the experiment's and the staircase's pure logic load without aiohttp.
"""
