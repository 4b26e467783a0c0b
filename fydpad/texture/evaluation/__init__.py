"""Evaluation and identification of texture models of every family: spectra of a
synthesis against a recording and the ceiling (``evaluate``), the nearest model to each
scan and the families side by side (``identify``)."""
