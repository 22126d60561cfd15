"""
Gymnasium environments over the core world: one (:mod:`.env`), N at once (:mod:`.vector`).

What they learn is :mod:`.tasks`; :mod:`.autoload` registers the ``sim/`` ids when Gymnasium's
registry loads.
"""
