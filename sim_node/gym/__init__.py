"""Gymnasium environments over the core world: one (:mod:`.env`), N at once (:mod:`.vector`)."""
