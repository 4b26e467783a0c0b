"""Texture rendering (issue 7): speed-indexed LPC models of real surfaces, fitted from
scan recordings, interpolated stably over speed and synthesized at 1 kHz (paper III-B).

Station API: :class:`fydpad.texture.synthesis.TextureRenderer` (``tick`` per sample,
``block`` per block) and :class:`fydpad.texture.synthesis.CentroidSpeed`.
"""
