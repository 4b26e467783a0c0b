"""Texture rendering: models of real surfaces fitted from scan recordings and rendered
at 1 kHz. ``family`` is the contract every family meets, ``families`` the registry and
the families (LPC, HaTT, friction, grating, MLP), ``evaluation`` the scoring and
identification of every family, ``operations`` what ``fydpad texture`` runs."""
