"""Energy margins inside the simulators users already have: Gymnasium, dm_control, a running MuJoCo model.

* :mod:`energy_margin.integrations.live_model`: the scorer of a user's ``MjModel`` / ``MjData``
  state and the episode recorder (the shared mechanism).
* :mod:`energy_margin.integrations.gymnasium`: ``MarginWrapper`` (``pip install 'energy-margin[gymnasium]'``).
* :mod:`energy_margin.integrations.dm_control`: ``MarginEnvironment`` and ``PhysicsScorer``
  (``pip install 'energy-margin[dm]'``).
* :mod:`energy_margin.integrations.gym_scene`: a starter scene file from a Gymnasium environment.

Nothing here is imported by ``import energy_margin``: each module imports its simulator library.
"""
