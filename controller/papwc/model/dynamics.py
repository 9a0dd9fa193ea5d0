"""The plant as real machines are: Eq. (1) and its deviations, one state, one step.

Standard library only (bundled into FrictionPlant.fmu). :class:`Plant` holds
the plant's parameters and its full state, and advances it over a
communication step with the force held (:meth:`Plant.step`). FrictionPlant.fmu
and the master's in-process plant (:class:`papwc.master.slave.PhysicsSlave`)
both step a :class:`Plant`, so they give the same trajectory to the last bit, and
both read its outputs by the model layer's names from :data:`OUTPUTS`.

How a step is computed depends on the deviations present
(:mod:`papwc.model.effects`):

- none: :func:`papwc.model.stickslip.step`, the exact closed form of Eq. (1),
  called exactly as before the deviations existed;
- only random stiction and/or encoder noise: still the closed form, piece by
  piece (the breakaway force is redrawn where the mass sticks inside the step);
- any of Stribeck, LuGre, ripple, actuator lag, flexible mode: no closed form;
  the state is integrated with RODAS4 (:mod:`papwc.model.rodas`, order 4,
  L-stable) under error control, and the stick-slip switches are events
  located inside the step: a sliding mass stops where its velocity reaches 0
  (then it sticks, with v exactly 0, or reverses), a stuck mass breaks away
  where the force on the table exceeds the breakaway force ``r(x)*f_s``.
  Each event is bracketed on the step's continuous extension, bisected to
  a relative width of 2**-45 of the step, and the state at the event is
  recomputed by a RODAS4 step that ends there. With LuGre the mass never
  sticks and there is no event.

The local error of every accepted RODAS4 step satisfies, componentwise,
``|err_i| <= atol_i + rtol_i*|y_i|`` with the tolerances of :data:`TOLERANCES`
(the bristle deflection z is held to the force sigma_0*z).

A stuck table driven through the lag alone (no flexible mode) needs no
integration either: the applied force is ``u + (f_a - u)*exp(-t/tau_u)`` and
the breakaway instant, where it reaches ``r(x)*f_s``, its logarithm.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from operator import attrgetter
from typing import Any

from .effects.encoder import MOTOR_STREAM, EncoderNoise
from .effects.flexible import FlexibleMode
from .effects.lag import ActuatorLag
from .effects.lugre import LuGre
from .effects.ripple import Ripple
from .effects.stiction import RandomStiction
from .effects.stribeck import Stribeck
from .plant import PLANT_DEFAULTS, PLANT_OUTPUTS
from .rodas import dense, dense_value, rodas4_step
from .stickslip import quantize, stop_time
from .stickslip import step as exact_step

__all__ = [
    "MAX_EVENTS",
    "MAX_STEPS",
    "OUTPUTS",
    "STATE_FIELDS",
    "TOLERANCES",
    "Plant",
    "output_reader",
]

#: Tolerances of the integrator's local error per state component, (absolute, relative):
#: ``|err| <= absolute + relative*|y|``. Forces (f_a, and sigma_0*z for z) in units of f_s.
TOLERANCES: dict[str, tuple[float, float]] = {
    "x": (1e-12, 1e-10),  # m
    "v": (1e-10, 1e-8),  # m/s
    "x_d": (1e-11, 1e-9),  # m
    "v_d": (1e-9, 1e-7),  # m/s
    "z": (1e-7, 1e-7),  # f_s/sigma_0 (a force error of 1e-7*f_s)
    "f_a": (1e-7, 1e-7),  # f_s
}
#: Most integrator steps in one communication step (more: the step is refused).
MAX_STEPS = 200_000
#: Most stick-slip events in one communication step (more: the step is refused).
MAX_EVENTS = 10_000

#: The plant's state, as :meth:`Plant.state` gives it.
STATE_FIELDS = ("x", "v", "z", "x_d", "v_d", "f_a", "f_s_now", "stick_draws", "noise_draws",
                "noise", "h_next")
_INT_FIELDS = ("stick_draws", "noise_draws")

_isfinite = math.isfinite
_INF = math.inf
#: Points of an accepted step (fractions of it) where the event functions are looked at.
_EVENT_SAMPLES = (0.25, 0.5, 0.75)
#: Bisection of an event stops at this width (fraction of the step).
_EVENT_WIDTH = 2.0**-45


class Plant:
    """The friction plant's parameters and full state, advanced one communication step at a time.

    Parameters
    ----------
    params : mapping
        Plant parameters by name (:data:`papwc.model.plant.PLANT_PARAMETERS`;
        missing ones take their defaults). They are not checked here: check
        them with :func:`papwc.model.plant.plant_problems` first.

    Attributes
    ----------
    x, v : float
        Table position (m) and velocity (m/s); ``v`` is exactly 0.0 while the
        table is stuck.
    z : float
        LuGre bristle deflection, m.
    x_d, v_d : float
        Motor position (m) and velocity (m/s) of the flexible drive.
    f_a : float
        Force applied by the lagging actuator, N.
    f_s_now : float
        Breakaway force in effect (random stiction), N.
    stick_draws, noise_draws : int
        Numbers drawn so far by random stiction; communication points so far when an
        encoder is noisy (the table's or the motor's).
    noise : float
        Encoder noise at the last communication point, m (the motor encoder's is drawn
        from the counter by :meth:`x_d_meas`).
    h_next : float
        The integrator's step size proposal, s (0: none yet).
    exact : bool
        No deviation needs integration: each step is the closed form.
    is_eq1 : bool
        No deviation at all: :meth:`step` is :func:`papwc.model.stickslip.step`.

    Examples
    --------
    Table 1's plant (m = 150 kg, f_c = 100 N, f_s = 130 N, c = 700 N.s/m) pushed with 300 N
    for 0.05 s from rest, then left to friction; it sticks again at 3.63 mm:

    >>> plant = Plant({"m": 150.0, "f_c": 100.0, "f_s": 130.0, "c": 700.0})
    >>> for k in range(20):
    ...     refused = plant.step(300.0 if k < 5 else 0.0, 0.01)
    >>> refused is None, plant.is_stuck(), round(plant.x, 7)
    (True, True, 0.0036329)
    >>> plant.outputs()["x_meas"] == plant.x  # an ideal encoder
    True
    """

    def __init__(self, params: Mapping[str, Any]) -> None:
        p = {**PLANT_DEFAULTS, **params}
        self.m, self.f_c, self.f_s, self.c = p["m"], p["f_c"], p["f_s"], p["c"]
        self.x0, self.v0, self.x_resolution = p["x0"], p["v0"], p["x_resolution"]
        seed = int(p["seed"])
        self.stribeck = Stribeck(p["v_s"], p["delta_s"]) if p["v_s"] > 0.0 else None
        self.lugre = LuGre(p["sigma_0"], p["sigma_1"]) if p["sigma_0"] > 0.0 else None
        self.ripple = (Ripple(p["ripple"], p["ripple_period"], p["ripple_phase"])
                       if p["ripple"] > 0.0 else None)
        self.stiction = (RandomStiction(p["f_s"], p["f_s_spread"], seed)
                         if p["f_s_spread"] > 0.0 else None)
        self.lag = ActuatorLag(p["tau_u"]) if p["tau_u"] > 0.0 else None
        self.flexible = FlexibleMode(p["m_d"], p["k_t"], p["c_t"]) if p["m_d"] > 0.0 else None
        self.encoder = EncoderNoise(p["noise_std"], seed) if p["noise_std"] > 0.0 else None
        self.x_d_resolution = p["x_d_resolution"]
        self.encoder_d = (EncoderNoise(p["x_d_noise_std"], seed, MOTOR_STREAM)
                          if p["x_d_noise_std"] > 0.0 else None)
        #: Some encoder is noisy: ``noise_draws`` counts the communication points.
        self.noisy = self.encoder is not None or self.encoder_d is not None
        self.exact = not (self.stribeck or self.lugre or self.ripple or self.lag
                          or self.flexible)
        #: (integrator steps, stick-slip events) of the last integrated communication step:
        #: the work a step took, which the model layer's ranges and rules bound.
        self.work = (0, 0)
        self.is_eq1 = self.exact and self.stiction is None and not self.noisy
        self._layout()
        self.reset()

    # -- state ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """The state at the start: at x0 with v0, spring relaxed, no force applied, draw 0."""
        self.x = self.x0
        self.v = self.v0
        self.z = 0.0
        self.x_d = self.x0
        self.v_d = self.v0
        self.f_a = 0.0
        self.f_s_now = self.f_s
        self.stick_draws = 0
        self.noise_draws = 0
        self.noise = 0.0
        self.h_next = 0.0
        if self.stiction is not None:
            self.f_s_now = self.stiction.draw(0)
            self.stick_draws = 1
        if self.noisy:
            if self.encoder is not None:
                self.noise = self.encoder.draw(0)
            self.noise_draws = 1

    def state(self) -> dict[str, float | int]:
        """The full state, restored exactly by :meth:`set_state`.

        Returns
        -------
        dict of str to float or int
            By :data:`STATE_FIELDS`; JSON-able.
        """
        return {name: getattr(self, name) for name in STATE_FIELDS}

    def set_state(self, values: Mapping[str, Any]) -> None:
        """Restore a state of :meth:`state`.

        Parameters
        ----------
        values : mapping of str to float or int
            A state as :meth:`state` returned it.

        Raises
        ------
        ValueError
            If a field is missing, unknown, of the wrong type or not finite; the
            state is then left as it was.
        """
        if not isinstance(values, Mapping) or sorted(values) != sorted(STATE_FIELDS):
            raise ValueError(f"a plant state has the fields {', '.join(STATE_FIELDS)}")
        for name in STATE_FIELDS:
            value = values[name]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"plant state field {name} = {value!r} is not a number")
            if name in _INT_FIELDS and not (isinstance(value, int) and value >= 0):
                raise ValueError(f"plant state field {name} = {value!r} is not a count")
            if not _isfinite(value):
                raise ValueError(f"plant state field {name} = {value!r} is not finite")
        for name in STATE_FIELDS:
            setattr(self, name, values[name] if name in _INT_FIELDS else float(values[name]))

    def x_meas(self) -> float:
        """Position read by the encoder (the output ``x_meas``).

        Returns
        -------
        float
            ``x`` plus the encoder noise, rounded to ``x_resolution``, m.
        """
        if self.encoder is None:
            return quantize(self.x, self.x_resolution)
        return quantize(self.x + self.noise, self.x_resolution)

    def is_stuck(self) -> bool:
        """Whether the table is at rest (the output ``stuck``).

        Returns
        -------
        bool
            ``v`` is exactly 0.
        """
        return self.v == 0.0

    def x_d_now(self) -> float:
        """Motor (drive) position (the output ``x_d``).

        Returns
        -------
        float
            ``x_d`` of the flexible drive, ``x`` on a rigid one, m.
        """
        return self.x if self.flexible is None else self.x_d

    def x_d_meas(self) -> float:
        """Position read by the motor encoder, m.

        ``quantize(x_d + x_d_noise_std*N_k, x_d_resolution)``: the law of :meth:`x_meas`
        with the motor encoder's parameters and its own stream of draws, at the same
        communication point ``k = noise_draws - 1``.

        Returns
        -------
        float
            The reading, m (the output ``x_d_meas``).
        """
        x_d = self.x_d_now()
        if self.encoder_d is None:
            return quantize(x_d, self.x_d_resolution)
        return quantize(x_d + self.encoder_d.draw(self.noise_draws - 1), self.x_d_resolution)

    def outputs(self) -> dict[str, Any]:
        """Every output now.

        Returns
        -------
        dict of str to float or bool
            By the model layer's names (:data:`OUTPUTS`, in that order).
        """
        return {name: value(self) for name, value in OUTPUTS.items()}

    # -- stepping ------------------------------------------------------------------------------
    def step(self, u: float, h: float) -> str | None:
        """Advance over one communication step with the force held (zero-order hold).

        Without deviations (:attr:`is_eq1`) this is :func:`papwc.model.stickslip.step`,
        Eq. (1) in closed form, called exactly as before the deviations existed.

        Parameters
        ----------
        u : float
            Force held over the step, N (finite).
        h : float
            Step size, s (> 0).

        Returns
        -------
        str or None
            None, or why the step is refused (the state is then left as it was).

        Examples
        --------
        >>> plant = Plant({})  # Table 1's plant, at rest at x0 = 0
        >>> plant.step(120.0, 0.01), plant.x  # below f_s = 130 N: it stays stuck
        (None, 0.0)
        >>> plant.step(300.0, 0.01), f"{plant.x:.6e}"  # above: it breaks away
        (None, '6.564162e-05')
        """
        if not self.is_eq1:
            return self._step_checked(u, h)
        x, v = exact_step(self.x, self.v, u, h, self.m, self.f_c, self.f_s, self.c)
        if not (_isfinite(x) and _isfinite(v)):
            return "the result would not be finite"
        self.x = x
        self.v = v
        return None

    def _step_checked(self, u: float, h: float) -> str | None:
        """Advance with deviations; on any failure the state is left as it was."""
        saved = self.state()
        try:
            if self.exact:
                reason = self._advance_stiction(u, h)
            else:
                reason = self._integrate(u, h)
        except (ArithmeticError, ValueError) as exc:
            reason = f"the integration failed: {type(exc).__name__}: {exc}"
        if reason is None and not all(_isfinite(getattr(self, n)) for n in STATE_FIELDS):
            reason = "the result would not be finite"
        if reason is not None:
            for name, value in saved.items():
                setattr(self, name, value)
            return reason
        if self.noisy:
            if self.encoder is not None:
                self.noise = self.encoder.draw(self.noise_draws)
            self.noise_draws += 1
        return None

    def _advance_stiction(self, u: float, h: float) -> None:
        """Eq. (1) in closed form with the breakaway force redrawn where the mass sticks."""
        m, f_c, c = self.m, self.f_c, self.c
        v = self.v
        x1, v1 = exact_step(self.x, v, u, h, m, f_c, self.f_s_now, c)
        if v != 0.0 and v1 == 0.0:
            # Stuck inside (or at the end of) the step: a new breakaway force holds from there.
            self._redraw()
            if not -self.f_s_now <= u <= self.f_s_now:
                t_stick = stop_time(v, u, m, f_c, c)
                if t_stick < h:
                    x1, v1 = exact_step(x1, 0.0, u, h - t_stick, m, f_c, self.f_s_now, c)
        self.x, self.v = x1, v1

    def _redraw(self) -> None:
        if self.stiction is not None:
            self.f_s_now = self.stiction.draw(self.stick_draws)
            self.stick_draws += 1

    # -- the integrated model ------------------------------------------------------------------
    def _layout(self) -> None:
        """Indexes of the state vector (x, v, then z, x_d, v_d, f_a where present)."""
        names = ["x", "v"]
        if self.lugre is not None:
            names.append("z")
        if self.flexible is not None:
            names += ["x_d", "v_d"]
        if self.lag is not None:
            names.append("f_a")
        self._names = names
        index = {name: i for i, name in enumerate(names)}
        self._iz = index.get("z", -1)
        self._ixd = index.get("x_d", -1)
        self._ivd = index.get("v_d", -1)
        self._ifa = index.get("f_a", -1)
        force = max(self.f_s, self.f_c, 1.0)
        scale = {"f_a": force, "z": force / self.lugre.sigma_0 if self.lugre is not None else 1.0}
        self._atol = [TOLERANCES[name][0] * scale.get(name, 1.0) for name in names]
        self._rtol = [TOLERANCES[name][1] for name in names]

    def _level(self, x: float, v: float, s: float) -> tuple[float, float, float]:
        """Steady sliding friction ``g`` (N) at (x, v) and its derivatives by x and v.

        ``s`` is the direction of motion, used for the slope at v = 0.
        """
        f_c = self.f_c
        if self.stribeck is not None:
            shape, slope = self.stribeck.shape(abs(v))
            rise = self.f_s_now - f_c
            base = self.f_s_now if shape == 1.0 else f_c + rise * shape
            sgn = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else s)
            base_v = rise * slope * sgn
        else:
            base, base_v = f_c, 0.0
        if self.ripple is not None:
            r, r_x = self.ripple.factor(x)
            return r * base, r_x * base, r * base_v
        return base, 0.0, base_v

    def _breakaway(self, x: float) -> float:
        """The force the stuck table holds before it breaks away, N."""
        if self.ripple is not None:
            return self.ripple.factor(x)[0] * self.f_s_now
        return self.f_s_now

    def _drive(self, y: list[float], u: float) -> float:
        """Force on the table from the drive, N."""
        if self.flexible is not None:
            return self.flexible.coupling(y[0], y[1], y[self._ixd], y[self._ivd])
        if self.lag is not None:
            return y[self._ifa]
        return u

    def _rates_at(self, u: float, s: float) -> Callable[[list[float]], list[float]]:
        """dy/dt as a function of the state alone, for the force ``u`` and direction ``s``."""
        rates = self._rates

        def f(y: list[float]) -> list[float]:
            return rates(y, u, s)

        return f

    def _rates(self, y: list[float], u: float, s: float) -> list[float]:
        """dy/dt; ``s``: direction of sliding, 0 while stuck (stick-slip model)."""
        out = [0.0] * len(y)
        x, v = y[0], y[1]
        f_a = y[self._ifa] if self.lag is not None else u
        if self.lag is not None:
            out[self._ifa] = self.lag.rate(f_a, u)
        if self.flexible is not None:
            flex = self.flexible
            v_d = y[self._ivd]
            drive = flex.coupling(x, v, y[self._ixd], v_d)
            out[self._ixd] = v_d
            out[self._ivd] = (f_a - drive) / flex.m_d
        else:
            drive = f_a
        if self.lugre is not None:
            sgn = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
            g = self._level(x, v, sgn)[0]
            z = y[self._iz]
            z_rate = self.lugre.rate(v, z, g)
            out[0] = v
            out[1] = (drive - self.lugre.force(z, z_rate) - self.c * v) / self.m
            out[self._iz] = z_rate
        elif s != 0.0:
            out[0] = v
            out[1] = (drive - s * self._level(x, v, s)[0] - self.c * v) / self.m
        return out

    def _jacobian(self, y: list[float], u: float, s: float) -> list[list[float]]:
        """d(dy/dt)/dy at ``y`` (see :meth:`_rates`)."""
        n = len(y)
        jac = [[0.0] * n for _ in range(n)]
        x, v = y[0], y[1]
        inv_m = 1.0 / self.m
        # Partial derivatives of the drive force on the table.
        drive_partials: list[tuple[int, float]] = []
        if self.lag is not None:
            jac[self._ifa][self._ifa] = -self.lag.rate_gain
        if self.flexible is not None:
            flex = self.flexible
            ixd, ivd = self._ixd, self._ivd
            drive_partials = [(ixd, flex.k_t), (0, -flex.k_t), (ivd, flex.c_t), (1, -flex.c_t)]
            inv_md = 1.0 / flex.m_d
            jac[ixd][ivd] = 1.0
            row = jac[ivd]
            for j, d in drive_partials:
                row[j] -= d * inv_md
            if self.lag is not None:
                row[self._ifa] += inv_md
        elif self.lag is not None:
            drive_partials = [(self._ifa, 1.0)]
        if self.lugre is None and s == 0.0:
            return jac
        jac[0][1] = 1.0
        row = jac[1]
        for j, d in drive_partials:
            row[j] += d * inv_m
        if self.lugre is not None:
            sgn = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
            g, g_x, g_v = self._level(x, v, sgn)
            iz = self._iz
            z = y[iz]
            dz_x, dz_v, dz_z = self.lugre.partials(v, z, g, g_x, g_v)
            s1 = self.lugre.sigma_1
            row[0] -= s1 * dz_x * inv_m
            row[1] -= (s1 * dz_v + self.c) * inv_m
            row[iz] -= (self.lugre.sigma_0 + s1 * dz_z) * inv_m
            jac[iz][0], jac[iz][1], jac[iz][iz] = dz_x, dz_v, dz_z
        else:
            _, g_x, g_v = self._level(x, v, s)
            row[0] -= s * g_x * inv_m
            row[1] -= (s * g_v + self.c) * inv_m
        return jac

    def _error(self, y: list[float], y1: list[float], err: list[float]) -> float:
        """The largest error of a step relative to its tolerance (<= 1: accepted)."""
        worst = 0.0
        for e, a, b, atol, rtol in zip(err, y, y1, self._atol, self._rtol, strict=True):
            q = abs(e) / (atol + rtol * max(abs(a), abs(b)))
            if not q <= worst:
                worst = q  # a NaN error makes the step rejected
        return worst

    def _pack(self) -> list[float]:
        return [getattr(self, name) for name in self._names]

    def _unpack(self, y: list[float]) -> None:
        for name, value in zip(self._names, y, strict=True):
            setattr(self, name, value)

    def _mode(self, y: list[float], u: float) -> float:
        """Direction of sliding at a state (0: stuck) for the stick-slip model."""
        v = y[1]
        if v != 0.0:
            return 1.0 if v > 0.0 else -1.0
        drive = self._drive(y, u)
        if abs(drive) > self._breakaway(y[0]):
            return 1.0 if drive > 0.0 else -1.0
        return 0.0

    def _integrate(self, u: float, h_total: float) -> str | None:
        """Integrate over one communication step with the stick-slip events; None or why not."""
        y = self._pack()
        lugre = self.lugre is not None
        s = 0.0 if lugre else self._mode(y, u)
        # While stuck without lag or flexible drive, nothing moves and the force is constant.
        frozen = self.lag is None and self.flexible is None
        t = 0.0
        h = self.h_next if self.h_next > 0.0 else h_total / 8.0
        steps = events = 0
        self.work = (0, 0)
        while t < h_total:
            if s == 0.0 and not lugre:
                if frozen:
                    break
                if self.flexible is None:
                    t_break = self._stuck_lag(y, u, h_total - t)
                    if t_break is None:
                        break
                    t += t_break
                    events += 1
                    s = self._switch(y, u, s)
                    continue
            remaining = h_total - t
            last = h >= remaining
            if last:
                h = remaining
            rates = self._rates_at(u, s)
            try:
                y1, stages, q, h, steps, shrunk = self._accepted_step(
                    rates, y, u, s, h, steps, 1e-15 * h_total)
            except ArithmeticError as exc:
                return str(exc)
            last = last and not shrunk
            grow = min(5.0, 0.9 * q**-0.25) if q > 0.0 else 5.0
            theta = None if lugre else self._event(y, y1, stages, u, s)
            if theta is None:
                y = y1
                t = h_total if last else t + h
                h *= grow
                continue
            # An event inside the step: recompute the state where it happens.
            events += 1
            self.work = (steps, events)
            if events > MAX_EVENTS:
                return (f"more than {MAX_EVENTS} stick-slip events in one communication "
                        "step")
            h_event = theta * h
            y, taken = self._advance_to(y, u, s, h_event)
            steps += taken
            t += h_event
            s = self._switch(y, u, s)
        self._unpack(y)
        self.h_next = h
        self.work = (steps, events)
        return None

    def _stuck_lag(self, y: list[float], u: float, remaining: float) -> float | None:
        """A stuck table under the lagging force over ``remaining`` (s), in closed form.

        ``y`` advances (in place) to the breakaway instant if the applied force
        reaches the breakaway force within ``remaining``, and its time is
        returned; else to the end (None).
        """
        ifa = self._ifa
        tau = self.lag.tau_u
        f0 = y[ifa]
        limit = self._breakaway(y[0])
        if abs(u) > limit:
            bound = limit if u > 0.0 else -limit
            t_break = max(0.0, tau * math.log((f0 - u) / (bound - u)))
            if t_break < remaining:
                f_a = f0 - (u - f0) * math.expm1(-t_break / tau)
                if not abs(f_a) > limit:
                    # Rounding: the force that breaks the table away exceeds the limit.
                    f_a = math.nextafter(bound, u)
                y[ifa] = f_a
                return t_break
        y[ifa] = f0 - (u - f0) * math.expm1(-remaining / tau)
        return None

    def _advance_to(self, y: list[float], u: float, s: float, h_end: float
                    ) -> tuple[list[float], int]:
        """Integrate exactly over ``h_end`` (s) without events; return the state and steps."""
        rates = self._rates_at(u, s)
        t = 0.0
        h = h_end
        steps = 0
        while t < h_end:
            remaining = h_end - t
            last = h >= remaining
            if last:
                h = remaining
            y1, _, q, h, steps, shrunk = self._accepted_step(rates, y, u, s, h, steps, 0.0)
            last = last and not shrunk
            y = y1
            t = h_end if last else t + h
            h *= min(5.0, 0.9 * q**-0.25) if q > 0.0 else 5.0
        return y, steps

    def _accepted_step(self, rates: Any, y: list[float], u: float, s: float, h: float,
                       steps: int, h_floor: float) -> tuple[list[float], tuple, float, float,
                                                            int, bool]:
        """One RODAS4 step from ``y`` that meets the tolerance, shrinking ``h`` (s) until it does.

        Returns the new state, the stages, the error norm q (<= 1), the step size
        taken, the steps counted so far and whether ``h`` was shrunk. Raises
        ArithmeticError past ``MAX_STEPS`` steps or when ``h`` falls to ``h_floor``.
        """
        f0 = rates(y)
        jac = self._jacobian(y, u, s)
        shrunk = False
        while True:
            steps += 1
            if steps > MAX_STEPS:
                raise ArithmeticError(f"the integrator needed more than {MAX_STEPS} steps in "
                                      "one communication step")
            y1, err, stages = rodas4_step(rates, y, f0, jac, h)
            if s == 0.0 and self.lugre is None:
                # Stuck: the table does not move (exactly, whatever the rounding).
                y1[0], y1[1], err[0], err[1] = y[0], 0.0, 0.0, 0.0
            q = self._error(y, y1, err)
            if q <= 1.0:
                return y1, stages, q, h, steps, shrunk
            h *= max(0.1, 0.9 * q**-0.25) if _isfinite(q) else 0.1
            shrunk = True
            if h <= h_floor:
                raise ArithmeticError(f"the integrator's step size fell below {h!r} s")

    def _event(self, y: list[float], y1: list[float], stages: tuple[list[float], ...],
               u: float, s: float) -> float | None:
        """Fraction of the step where the first stick-slip event happens, or None.

        Sliding (s != 0): the velocity reaches 0 (``s*v <= 0``). Stuck: the drive
        force exceeds the breakaway force (``|F| - r(x)*f_s > 0``).
        """
        if s != 0.0:
            v_of = dense(y[1], y1[1], stages, 1)

            def crossed(theta: float) -> bool:
                return s * (y1[1] if theta == 1.0 else dense_value(v_of, theta)) <= 0.0
        else:
            if self.lag is None and self.flexible is None:
                return None
            limit = self._breakaway(y[0])
            moving = [i for i in (self._ixd, self._ivd, self._ifa) if i >= 0]
            of = [(i, dense(y[i], y1[i], stages, i)) for i in moving]
            state = list(y)

            def crossed(theta: float) -> bool:
                if theta == 1.0:
                    return abs(self._drive(y1, u)) > limit
                for i, coefficients in of:
                    state[i] = dense_value(coefficients, theta)
                return abs(self._drive(state, u)) > limit
        lo = 0.0
        for theta in (*_EVENT_SAMPLES, 1.0):
            if crossed(theta):
                hi = theta
                break
            lo = theta
        else:
            return None
        while hi - lo > _EVENT_WIDTH:
            mid = 0.5 * (lo + hi)
            if crossed(mid):
                hi = mid
            else:
                lo = mid
        return hi

    def _switch(self, y: list[float], u: float, s: float) -> float:
        """Apply a stick-slip event at state ``y`` (in place); return the new direction.

        A sliding mass that stops sticks (v = 0 exactly; random stiction draws
        a new breakaway force, and the mass breaks away at once if the force
        exceeds it) or reverses if the force exceeds the breakaway force; a
        stuck mass breaks away in the direction of the force.
        """
        drive = self._drive(y, u)
        if s != 0.0:
            y[1] = 0.0
            if abs(drive) <= self._breakaway(y[0]):
                self._redraw()
                if abs(drive) <= self._breakaway(y[0]):
                    return 0.0
        return 1.0 if drive > 0.0 else -1.0


#: The plant's outputs, by the names and in the order of :data:`papwc.model.plant.PLANT_OUTPUTS`:
#: the function of a :class:`Plant` that gives each now. Every reader of the outputs takes
#: them from here: the master's in-process plant (:class:`papwc.master.slave.PhysicsSlave`),
#: FrictionPlant.fmu built with pythonfmu, and so the observers and the traces. A new output
#: is its :class:`~papwc.model.variables.Variable` in ``PLANT_OUTPUTS`` and its function here
#: (and, for the native FMU, its line in ``fp_outputs`` of fmu_src/FrictionPlant/plant.c).
OUTPUTS: dict[str, Callable[[Plant], Any]] = {
    "x": attrgetter("x"),
    "v": attrgetter("v"),
    "x_meas": Plant.x_meas,
    "stuck": Plant.is_stuck,
    "x_d": Plant.x_d_now,
    "x_d_meas": Plant.x_d_meas,
}

if tuple(OUTPUTS) != tuple(var.name for var in PLANT_OUTPUTS):
    raise ImportError("papwc.model.dynamics.OUTPUTS must compute the outputs of "
                      "papwc.model.plant.PLANT_OUTPUTS, in their order: "
                      + ", ".join(var.name for var in PLANT_OUTPUTS))


def output_reader(names: Sequence[str]) -> Callable[[Plant], list[Any]]:
    """A reader of some outputs of a :class:`Plant`.

    Parameters
    ----------
    names : sequence of str
        Output names (:data:`OUTPUTS`), in the order they are read.

    Returns
    -------
    callable
        ``read(plant)``: the outputs ``names`` of ``plant`` now, as a new list.

    Raises
    ------
    KeyError
        If a name is not an output (:data:`OUTPUTS`).
    """
    values = [OUTPUTS[name] for name in names]

    def read(plant: Plant) -> list[Any]:
        return [value(plant) for value in values]

    return read
