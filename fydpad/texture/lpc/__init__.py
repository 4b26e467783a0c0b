"""The LPC texture family (Bianchi 2015 III-B): analysis (``analysis``, ``dft321``,
``lsf``), the fits and their validation (``fit``, ``select``, ``spectrum``),
interpolation over speed, the renderer (``synthesis``),
the model file and speed coverage, and the adapter to the family contract (``family``)."""
