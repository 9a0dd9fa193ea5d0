"""One step of the Rosenbrock method RODAS4, with its error estimate and dense output.

Standard library only (bundled into FrictionPlant.fmu). RODAS4 (Hairer and
Wanner, *Solving Ordinary Differential Equations II*, 2nd ed., Springer 1996,
Section IV.7, method ``RODAS`` with its first coefficient set) is a linearly
implicit Runge-Kutta method of order 4 with six stages:

- L-stable and stiffly accurate: components far faster than the step (the
  LuGre bristles at sliding speed, a short actuator lag, a stiff coupling)
  are damped as they are in the exact solution instead of limiting the step;
- one inversion of ``I/(gamma*h) - J`` per step (J the exact Jacobian; the
  systems here have 2 to 6 states) and no Newton iteration, which matters in
  pure Python;
- an embedded order-3 solution: ``y_new - y_hat`` is the error estimate the
  step size control uses;
- a continuous extension of order 3 (:func:`dense`), used to locate events
  inside a step.

The system is autonomous, ``dy/dt = f(y)``: the force held over a
communication step makes the plant autonomous on it.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["GAMMA", "dense", "dense_value", "inverse", "matvec", "rodas4_step"]

GAMMA = 0.25
_A21 = 1.544
_A31, _A32 = 0.9466785280815826, 0.2557011698983284
_A41, _A42, _A43 = 3.314825187068521, 2.896124015972201, 0.9986419139977817
_A51, _A52, _A53, _A54 = (1.221224509226641, 6.019134481288629, 12.53708332932087,
                          -0.6878860361058950)
_C21 = -5.6688
_C31, _C32 = -2.430093356833875, -0.2063599157091915
_C41, _C42, _C43 = -0.1073529058151375, -9.594562251023355, -20.47028614809616
_C51, _C52, _C53, _C54 = (7.496443313967647, -10.24680431464352, -33.99990352819905,
                          11.70890893206160)
_C61, _C62, _C63, _C64, _C65 = (8.083246795921522, -7.981132988064893, -31.52159432874371,
                                16.31930543123136, -6.058818238834054)
# Continuous extension.
_D21, _D22, _D23, _D24, _D25 = (10.12623508344586, -7.487995877610167, -34.80091861555747,
                                -7.992771707568823, 1.025137723295662)
_D31, _D32, _D33, _D34, _D35 = (-0.6762803392801253, 6.087714651680015, 16.43084320892478,
                                24.76722511418386, -6.594389125716872)


# The products of the iteration matrix's inverse and a vector, written out for the plant's
# 2 to 6 states: each row's terms summed left to right, as the loop of _matvec_any does;
# written out, a RODAS4 step of the plant costs less (see matvec).
def _matvec2(m: list[list[float]], b: list[float]) -> list[float]:
    b0, b1 = b
    return [r[0] * b0 + r[1] * b1 for r in m]


def _matvec3(m: list[list[float]], b: list[float]) -> list[float]:
    b0, b1, b2 = b
    return [r[0] * b0 + r[1] * b1 + r[2] * b2 for r in m]


def _matvec4(m: list[list[float]], b: list[float]) -> list[float]:
    b0, b1, b2, b3 = b
    return [r[0] * b0 + r[1] * b1 + r[2] * b2 + r[3] * b3 for r in m]


def _matvec5(m: list[list[float]], b: list[float]) -> list[float]:
    b0, b1, b2, b3, b4 = b
    return [r[0] * b0 + r[1] * b1 + r[2] * b2 + r[3] * b3 + r[4] * b4 for r in m]


def _matvec6(m: list[list[float]], b: list[float]) -> list[float]:
    b0, b1, b2, b3, b4, b5 = b
    return [r[0] * b0 + r[1] * b1 + r[2] * b2 + r[3] * b3 + r[4] * b4 + r[5] * b5 for r in m]


def _matvec_any(m: list[list[float]], b: list[float]) -> list[float]:
    out = []
    for row in m:
        total = row[0] * b[0]
        for j in range(1, len(b)):
            total = total + row[j] * b[j]
        out.append(total)
    return out


_MATVEC: dict[int, Callable[[list[list[float]], list[float]], list[float]]] = {
    2: _matvec2, 3: _matvec3, 4: _matvec4, 5: _matvec5, 6: _matvec6,
}


def matvec(n: int) -> Callable[[list[list[float]], list[float]], list[float]]:
    """``matvec(m, b)``: the product of an n x n matrix (list of rows) and a vector.

    Every row's terms ``m[i][j]*b[j]`` are summed left to right. For the plant's
    2 to 6 states the product is written out term by term, which the measurement
    in ``papwc bench`` (section "RODAS4 step") shows to be worth it; other sizes
    take a loop.
    """
    return _MATVEC.get(n, _matvec_any)


def inverse(a: list[list[float]]) -> list[list[float]]:
    """The inverse of the square matrix ``a`` (Gauss-Jordan, partial pivoting; ``a`` is kept).

    Raises
    ------
    ZeroDivisionError
        If the matrix is singular.
    """
    n = len(a)
    if n == 2:
        (p, q), (r, s) = a
        det = p * s - q * r
        if det == 0.0:
            raise ZeroDivisionError("singular iteration matrix")
        return [[s / det, -q / det], [-r / det, p / det]]
    rows = [list(row) + [1.0 if i == j else 0.0 for j in range(n)] for i, row in enumerate(a)]
    width = 2 * n
    for k in range(n):
        p = k
        best = abs(rows[k][k])
        for i in range(k + 1, n):
            if abs(rows[i][k]) > best:
                p, best = i, abs(rows[i][k])
        if best == 0.0:
            raise ZeroDivisionError("singular iteration matrix")
        rows[k], rows[p] = rows[p], rows[k]
        pivot_row = rows[k]
        inv_pivot = 1.0 / pivot_row[k]
        for j in range(k, width):
            pivot_row[j] *= inv_pivot
        for i in range(n):
            if i != k:
                row = rows[i]
                factor = row[k]
                if factor != 0.0:
                    for j in range(k, width):
                        row[j] -= factor * pivot_row[j]
    return [row[n:] for row in rows]


def rodas4_step(
    f: Callable[[list[float]], list[float]],
    y: list[float],
    f0: list[float],
    jac: list[list[float]],
    h: float,
) -> tuple[list[float], list[float], tuple[list[float], ...]]:
    """One RODAS4 step of size ``h`` from ``y`` for ``dy/dt = f(y)``.

    Parameters
    ----------
    f : callable
        The right-hand side.
    y, f0 : list of float
        The state and ``f(y)``.
    jac : list of list of float
        The Jacobian ``df/dy`` at ``y`` (not modified).
    h : float
        Step size, > 0.

    Returns
    -------
    y_new : list of float
        The order-4 solution at the end of the step.
    err : list of float
        ``y_new`` minus the embedded order-3 solution (the local error estimate).
    stages : tuple of list of float
        ``k1`` ... ``k5``, for :func:`dense`.

    Raises
    ------
    ZeroDivisionError
        If ``I/(gamma*h) - J`` is singular.
    """
    n = len(y)
    r = range(n)
    diag = 1.0 / (GAMMA * h)
    a = [[-v for v in row] for row in jac]
    for i in r:
        a[i][i] += diag
    inv = inverse(a)
    mv = matvec(n)
    inv_h = 1.0 / h
    k1 = mv(inv, f0)
    f2 = f([y[i] + _A21 * k1[i] for i in r])
    c21 = _C21 * inv_h
    k2 = mv(inv, [f2[i] + c21 * k1[i] for i in r])
    f3 = f([y[i] + _A31 * k1[i] + _A32 * k2[i] for i in r])
    k3 = mv(inv, [f3[i] + inv_h * (_C31 * k1[i] + _C32 * k2[i]) for i in r])
    f4 = f([y[i] + _A41 * k1[i] + _A42 * k2[i] + _A43 * k3[i] for i in r])
    k4 = mv(inv, [f4[i] + inv_h * (_C41 * k1[i] + _C42 * k2[i] + _C43 * k3[i]) for i in r])
    y5 = [y[i] + _A51 * k1[i] + _A52 * k2[i] + _A53 * k3[i] + _A54 * k4[i] for i in r]
    f5 = f(y5)
    k5 = mv(inv, [f5[i] + inv_h * (_C51 * k1[i] + _C52 * k2[i] + _C53 * k3[i] + _C54 * k4[i])
                  for i in r])
    y6 = [y5[i] + k5[i] for i in r]
    f6 = f(y6)
    err = mv(inv, [f6[i] + inv_h * (_C61 * k1[i] + _C62 * k2[i] + _C63 * k3[i] + _C64 * k4[i]
                                    + _C65 * k5[i]) for i in r])
    return [y6[i] + err[i] for i in r], err, (k1, k2, k3, k4, k5)


def dense(y0: float, y1: float, stages: tuple[list[float], ...], i: int
          ) -> tuple[float, float, float, float]:
    """Coefficients of component ``i`` of the step's continuous extension (order 3).

    ``y0``, ``y1`` are component ``i`` at the start and the end of the step,
    ``stages`` the ``k`` of :func:`rodas4_step`; :func:`dense_value` evaluates it.
    """
    k1, k2, k3, k4, k5 = (k[i] for k in stages)
    return (y0, y1, _D21 * k1 + _D22 * k2 + _D23 * k3 + _D24 * k4 + _D25 * k5,
            _D31 * k1 + _D32 * k2 + _D33 * k3 + _D34 * k4 + _D35 * k5)


def dense_value(coefficients: tuple[float, float, float, float], theta: float) -> float:
    """The continuous extension of :func:`dense` at ``t0 + theta*h`` (0 <= theta <= 1)."""
    y0, y1, c3, c4 = coefficients
    s1 = 1.0 - theta
    return y0 * s1 + theta * (y1 + s1 * (c3 + theta * c4))
