"""The LPC texture family (Bianchi 2015 III-B): analysis (``analysis``, ``dft321``,
``lsf``), the fits and their validation (``fit``, ``select``, ``spectrum``, ``lines``),
interpolation over speed, the renderer (``synthesis``, ``fir_warp``, ``line_voice``),
the model file and speed coverage, and the adapter to the family contract (``family``)."""
