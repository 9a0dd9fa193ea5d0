"""The plant's deviations from Eq. (1), one module each (standard library only).

Each module holds one effect's parameters and equations behind a few methods
that :mod:`papwc.model.dynamics` composes into the plant's right-hand side and
its Jacobian:

- :mod:`.stribeck`: the Stribeck curve, the sliding friction's velocity shape
  ``S(v)`` between f_s (S = 1 at rest) and f_c (S -> 0);
- :mod:`.lugre`: the LuGre bristle state ``z`` (pre-sliding), its rate and the
  friction force it gives;
- :mod:`.ripple`: a position-dependent factor ``r(x)`` on the friction levels;
- :mod:`.stiction`: the breakaway force redrawn each time the mass sticks;
- :mod:`.lag`: a first-order lag between the force asked and the force applied;
- :mod:`.flexible`: a motor mass coupled to the table by a spring and a damper;
- :mod:`.encoder`: Gaussian noise added before the encoder's quantization;
- :mod:`.draws`: the reproducible random numbers of the two random effects.

An effect whose parameter is at its default (``v_s = 0``, ``sigma_0 = 0``,
``ripple = 0``, ``f_s_spread = 0``, ``tau_u = 0``, ``m_d = 0``,
``noise_std = 0``) is absent: the plant composes only the effects present, and
with none present it is exactly :func:`papwc.model.stickslip.step`.

A new effect is a module here (a class holding its parameters, with its
equation and, for a state, its partial derivatives), its parameters as
entries of :data:`papwc.model.plant.DEVIATION_PARAMETERS`, and one place in
:class:`papwc.model.dynamics.Plant` that uses it when present: the friction
level ``g(v, x)`` (``_level``), the breakaway force (``_breakaway``), the force
on the table (``_drive``), a state's rate and Jacobian rows (``_rates``,
``_jacobian``), or the encoder reading (``x_meas``).
"""
