"""The HaTT family (Culbertson 2014): model files (``toolkit``), the family (``render``)."""
