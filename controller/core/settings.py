"""Settings of a pulse controller: one ``[[controller]]`` table of a scenario file.

Standard library only. :func:`ControllerSettings.problems` is the one place the
settings are validated; the scenario reader and the controller FMU both use it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field


@dataclass
class ControllerSettings:
    """Settings of one controller. SI units; names follow the paper.

    Attributes
    ----------
    kind : str
        ``"pwc"`` (Section 2), ``"papwc"`` (Section 3) or ``"exact"``.
    f_p_max : float
        Largest pulse amplitude, N (PWC always pulses at f_p_max).
    t_p_max : float
        Largest pulse width, s; ``inf`` for no bound.
    K_c : float
        Gain of Eq. (6), 0 < K_c < 2.
    tolerance : float
        Error band, m, inside which the controller stops pulsing (>= 0).
    m_est : float
        Initial estimate of the mass, kg.
    f_c_est : float
        Initial estimate of the Coulomb friction, N.
    f_p_min : float or None
        Initial floor of the pulse amplitude, N; ``None`` means f_c_est. Raised
        whenever a pulse does not move the mass.
    floor_raise : float
        Relative step by which the amplitude floor rises above an amplitude
        that did not move the mass.
    F_inv0 : float
        F^-1(0) of the PWC estimator, Eq. (8) (paper: 1e-5).
    lambda_1, lambda_2 : float
        Forgetting parameters of Eq. (8).
    delta_inv : float
        P(0) = delta_inv * I of the PAPWC estimator, Eq. (13)-(17) (paper: 1e-5).
    lam : float
        Forgetting factor lambda of Eq. (14)-(15) (TOML key ``lambda``).
    e_band : float
        Error band, m, inside which the mass at rest is handed over from the
        coarse feedback to pulse mode.
    k_p, k_d : float or None
        Gains of the coarse PD feedback, N/m and N.s/m; ``None`` gives
        ``m_est*omega**2`` and ``2*0.7*omega*m_est`` with omega = 10 rad/s.
    rest_samples : int
        Samples with unchanged measured position that count as "at rest".
    rest_band : float
        Largest change of the measured position, m, that still counts as
        unchanged (0: exact equality, right for an ideal or quantized encoder;
        a few standard deviations of the noise for a noisy sensor).
    """

    kind: str = "papwc"
    f_p_max: float = 300.0
    t_p_max: float = math.inf
    K_c: float = 1.0
    tolerance: float = 2e-5
    m_est: float = 150.0
    f_c_est: float = 80.0
    f_p_min: float | None = None
    floor_raise: float = 0.05
    F_inv0: float = 1e-5
    lambda_1: float = 1.0
    lambda_2: float = 1.0
    delta_inv: float = 1e-5
    lam: float = 1.0
    e_band: float = 0.02
    k_p: float | None = None
    k_d: float | None = None
    rest_samples: int = 1
    rest_band: float = 0.0
    extra: dict = field(default_factory=dict)

    #: TOML keys that differ from the attribute names.
    KEY_ALIASES = {"lambda": "lam"}

    @classmethod
    def field_names(cls) -> list[str]:
        """Names of the settings as they are written in a scenario file."""
        inverse = {v: k for k, v in cls.KEY_ALIASES.items()}
        return [inverse.get(f.name, f.name) for f in dataclasses.fields(cls) if f.name != "extra"]

    @property
    def f_p_floor0(self) -> float:
        """Initial amplitude floor, N."""
        return self.f_c_est if self.f_p_min is None else self.f_p_min

    @property
    def k_p_value(self) -> float:
        """Proportional gain of the coarse feedback, N/m."""
        return self.m_est * 100.0 if self.k_p is None else self.k_p

    @property
    def k_d_value(self) -> float:
        """Derivative gain of the coarse feedback, N.s/m."""
        return 2.0 * 0.7 * 10.0 * self.m_est if self.k_d is None else self.k_d

    def problems(self, kinds: tuple[str, ...] | None = None) -> list[tuple[str, str]]:
        """Every invalid setting as ``(field, message)``; empty when valid."""
        out: list[tuple[str, str]] = []

        def bad(name: str, msg: str) -> None:
            value = getattr(self, self.KEY_ALIASES.get(name, name))
            out.append((name, f"{name} = {value!r}: {msg}"))

        if kinds is not None and self.kind not in kinds:
            bad("kind", f"must be one of {', '.join(repr(k) for k in kinds)}")
        optional = ("f_p_min", "k_p", "k_d")
        numeric = [n for n in self.field_names() if n != "kind" and n not in optional]
        numeric += [n for n in optional if getattr(self, n) is not None]
        for name in numeric:
            value = getattr(self, self.KEY_ALIASES.get(name, name))
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                bad(name, "must be a number")
            elif math.isnan(value) or (math.isinf(value) and name != "t_p_max"):
                bad(name, "must be finite")
        if out:
            return out
        if self.f_p_max <= 0.0:
            bad("f_p_max", "must be > 0 N")
        if not self.t_p_max > 0.0:
            bad("t_p_max", "must be > 0 s (inf for no bound)")
        if not 0.0 < self.K_c < 2.0:
            bad("K_c", "must satisfy 0 < K_c < 2 (Eq. (6))")
        if self.tolerance < 0.0:
            bad("tolerance", "must be >= 0 m")
        if self.m_est <= 0.0:
            bad("m_est", "must be > 0 kg")
        if not 0.0 < self.f_c_est < self.f_p_max:
            bad("f_c_est", f"must satisfy 0 < f_c_est < f_p_max = {self.f_p_max!r} N")
        if self.f_p_min is not None and not 0.0 <= self.f_p_min <= self.f_p_max:
            bad("f_p_min", f"must satisfy 0 <= f_p_min <= f_p_max = {self.f_p_max!r} N")
        if not 0.0 < self.floor_raise <= 1.0:
            bad("floor_raise", "must satisfy 0 < floor_raise <= 1")
        if self.F_inv0 <= 0.0:
            bad("F_inv0", "must be > 0")
        if not 0.0 < self.lambda_1 <= 1.0:
            bad("lambda_1", "must satisfy 0 < lambda_1 <= 1 (Eq. (8))")
        if not 0.0 <= self.lambda_2 < 2.0:
            bad("lambda_2", "must satisfy 0 <= lambda_2 < 2 (Eq. (8))")
        if self.delta_inv <= 0.0:
            bad("delta_inv", "must be > 0")
        if not 0.0 < self.lam <= 1.0:
            bad("lambda", "must satisfy 0 < lambda <= 1")
        if self.e_band <= self.tolerance:
            bad("e_band", f"must be > tolerance = {self.tolerance!r} m")
        if self.k_p is not None and self.k_p <= 0.0:
            bad("k_p", "must be > 0 N/m")
        if self.k_d is not None and self.k_d < 0.0:
            bad("k_d", "must be >= 0 N.s/m")
        if self.rest_band < 0.0:
            bad("rest_band", "must be >= 0 m")
        if int(self.rest_samples) != self.rest_samples or self.rest_samples < 1:
            bad("rest_samples", "must be a whole number >= 1")
        return out

    @classmethod
    def from_mapping(cls, values: dict) -> ControllerSettings:
        """Settings from a mapping with scenario-file keys; unknown keys go to ``extra``."""
        names = {f.name for f in dataclasses.fields(cls)}
        kwargs: dict = {}
        extra: dict = {}
        for key, value in values.items():
            attr = cls.KEY_ALIASES.get(key, key)
            if attr in names and attr != "extra":
                kwargs[attr] = value
            else:
                extra[key] = value
        return cls(**kwargs, extra=extra)

    def to_mapping(self) -> dict:
        """The settings with scenario-file keys (``None`` values left out)."""
        inverse = {v: k for k, v in self.KEY_ALIASES.items()}
        out = {}
        for f in dataclasses.fields(self):
            if f.name == "extra":
                continue
            value = getattr(self, f.name)
            if value is not None:
                out[inverse.get(f.name, f.name)] = value
        return out
