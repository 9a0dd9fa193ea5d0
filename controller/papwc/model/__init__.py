"""The model layer: the single source of truth of the physics and of every parameter.

Standard library only, so that the FMUs can bundle it under names of their own:

- :mod:`.stickslip`: the plant's motion, Eq. (1), advanced exactly over a step;
- :mod:`.dynamics`: the plant as real machines are (:class:`~.dynamics.Plant`),
  Eq. (1) plus the deviations of :mod:`.effects` (one module per effect),
  integrated with :mod:`.rodas` where no closed form exists;
- :mod:`.pulse`: the pulse model, Eq. (2)-(4), forward and inverse;
- :mod:`.variables`: what a parameter, setting, input or output is (name,
  unit, default, range) and how values are checked;
- :mod:`.plant`, :mod:`.maneuver`, :mod:`.controller_settings`: the tables of the plant's
  variables, the maneuver's fields and the controllers' settings and signals.
"""
