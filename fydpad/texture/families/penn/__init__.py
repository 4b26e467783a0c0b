"""The HaTT family (Culbertson 2014): the toolkit's model files, interpolation and
synthesis (``toolkit``), and the family that renders them at 1 kHz (``render``)."""
