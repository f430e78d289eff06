"""How fast a model moves at a state, and the step that resolves it; the energy check's
rule and messages (used by both paths of :func:`moreau.simulate`).

The energy check compares the kinetic energy T(q, v) = ½ vᵀ M(q) v with T₀ plus the work
of the applied forces (the smooth forces' work of ``traj.work`` less that of the bias
terms, which do none). Newton impacts (e <= 1) can only remove energy, so they are not
credited: energy above that is the scheme's own error, and an unstable step makes it grow
exponentially (a long chain's fast tail at h = 1e-3, for instance). Checked every
``ENERGY_CHECK_EVERY`` steps and after every step with a logged impact. Above a fraction
``warn`` of the largest kinetic energy so far the run warns once (also for a one-step
transient at an impact, which says the step is coarse for it); above ``stop`` at two checks in a row it stops with a
:class:`~moreau.SimulationError` that names the time, the energy gained, the step size and
a step size from the model's fastest mode at that state (:func:`stable_step`), keeping the
trajectory up to the last check that passed (below both bounds): the steps after it may
already be the runaway. The defaults (5 %, 10 %) leave alone the first-order energy drift of a
resolved run (a three-rod chain of 0.3 m at h = 1e-3 drifts by 2.9 % of its kinetic
energy in 2 s, 0.3 % at 1e-4).

With a constant mass matrix the ledger is blind to a step beyond the explicit forces'
stability limit (a step's kinetic energy change is the work of the forces it applied,
exactly): :func:`explicit_limit_message` names it before the run, and the check's runaway
test stops a run whose kinetic energy rises above its largest so far by more than e^0.4 a
step (an amplitude growing by a fifth a step, which no resolved motion does) at two checks
in a row (:func:`runaway_message`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["ENERGY_CHECK_EVERY", "DEFAULT_ENERGY_GROWTH", "EXPLICIT_LIMIT", "as_energy_growth", "fastest_rates",
           "explicit_limit_message", "stable_step",
           "step_advice", "kept_until", "not_converged_message", "energy_growth_message", "runaway_message"]

#: the check runs every this many steps (a mass-matrix evaluation each time)
ENERGY_CHECK_EVERY = 8
#: (warn, stop): fractions of the largest kinetic energy so far
DEFAULT_ENERGY_GROWTH = (0.05, 0.1)


def as_energy_growth(value: Any) -> tuple[float, float] | None:
    """``energy_growth`` checked: None (no check) or ``(warn, stop)`` with 0 < warn <= stop."""
    if value is None:
        return None
    try:
        warn, stop = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValueError(f"energy_growth must be None or (warn, stop), two fractions of the largest kinetic "
                         f"energy, got {value!r}") from None
    if not (0.0 < warn <= stop and math.isfinite(stop)):
        raise ValueError(f"energy_growth must satisfy 0 < warn <= stop (finite), got {value!r}")
    return warn, stop


def _jacobian(fun: Any, x: np.ndarray) -> np.ndarray:
    n = x.shape[0]
    J = np.empty((n, n))
    for j in range(n):
        eps = 1e-6 * (1.0 + abs(x[j]))
        dx = np.zeros(n)
        dx[j] = eps
        J[:, j] = (np.asarray(fun(x + dx), dtype=float) - np.asarray(fun(x - dx), dtype=float)) / (2.0 * eps)
    return J


def fastest_rates(scene: Any, t: float, q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """``(ω, ρ)`` at a state: ω the largest angular frequency of the linearized model,
    √ of the largest eigenvalue of −M⁻¹ ∂f/∂q, and ρ the spectral radius of M⁻¹ ∂f/∂v (the
    rate of the velocity-dependent forces, centrifugal terms included); both in 1/(time
    unit), from central differences of the scene's force."""
    return _rates(*_rate_matrices(scene, t, q, v))


def _rate_matrices(scene: Any, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(−M⁻¹ ∂f/∂q, M⁻¹ ∂f/∂v)`` at a state, each None where the derivative is zero."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    M = np.asarray(scene.system.mass_matrix(q), dtype=float)
    Kq = _jacobian(lambda x: scene.force(t, x, v), q)
    # no effect depends on v (the scene's flag, which the step's order relies on too): ∂f/∂v = 0
    Cv = _jacobian(lambda x: scene.force(t, q, x), v) if getattr(scene, "velocity_dependent", True) else None
    return ((np.linalg.solve(M, -Kq) if Kq.any() else None),
            (np.linalg.solve(M, Cv) if Cv is not None and Cv.any() else None))


def _rates(A: np.ndarray | None, B: np.ndarray | None) -> tuple[float, float]:
    """``(ω, ρ)`` of :func:`fastest_rates` from its matrices."""
    omega = math.sqrt(max(0.0, float(np.linalg.eigvals(A).real.max()))) if A is not None else 0.0
    rho = float(np.abs(np.linalg.eigvals(B)).max()) if B is not None else 0.0
    return omega, rho


def _norm(A: np.ndarray | None) -> float:
    """The largest absolute row sum of A (0 for None), a bound of its spectral radius."""
    return float(np.abs(A).sum(axis=1).max()) if A is not None else 0.0


#: the midpoint step applies the forces explicitly: a linear mode of angular frequency ω
#: grows without bound beyond h ω = 2 (the Störmer–Verlet bound), a velocity-dependent rate
#: ρ beyond h ρ = 2 (explicit damping)
EXPLICIT_LIMIT = 2.0


def explicit_limit_message(scene: Any, t: float, q: np.ndarray, v: np.ndarray, h: float) -> str | None:
    """The words of a step ``h`` beyond the midpoint step's stability limit at a state
    (``EXPLICIT_LIMIT`` = 2, :func:`fastest_rates`) for a system of constant mass, or None.
    The energy check cannot see that runaway there: a step's kinetic energy change equals the
    work of the forces it applied, exactly, unstable or not (a mass matrix that depends on q
    breaks that identity, and the check sees the growth)."""
    if not scene.system.constant_mass:
        return None
    try:
        A, B = _rate_matrices(scene, t, q, v)
        # ω² <= ρ(A) <= |A|_∞ and ρ <= |B|_∞: within the limit by the bounds, no eigenvalues needed
        if h * h * _norm(A) < EXPLICIT_LIMIT**2 and h * _norm(B) < EXPLICIT_LIMIT:
            return None
        omega, rho = _rates(A, B)
    except Exception:  # noqa: BLE001 - the initial-state checks name a force that fails
        return None
    if max(h * omega, h * rho) < EXPLICIT_LIMIT:
        return None
    rate, what = (omega, "angular frequency ω") if omega >= rho else (rho, "velocity-dependent rate ρ")
    return (f"h = {h:g} is beyond the stability limit of the midpoint step, whose forces are explicit, for this "
            f"model at t = {t:g}: its fastest {what} = {rate:.3g} per time unit gives h·{what[-1]} = {h * rate:.3g} "
            f"> {EXPLICIT_LIMIT:g}, and that motion grows without bound; take h < {EXPLICIT_LIMIT / rate:.2g} "
            f"(about h = {_resolving_step(omega, rho):.2g} resolves it)")


#: the step resolves a motion of angular frequency ω when h ω <= RESOLVE (about 16 steps per
#: period) and a velocity-dependent rate ρ when h ρ <= RESOLVE / 2
RESOLVE = 0.4


def stable_step(scene: Any, t: float, q: np.ndarray, v: np.ndarray) -> float:
    """A step size that resolves the model's fastest motion at a state (:func:`fastest_rates`):
    min(RESOLVE/ω, RESOLVE/(2ρ)); inf for a model with neither. A resolution rule, not a
    proven bound: faster motion later in the run needs a smaller step (the 40-link chain's
    whip reaches ω = 4500/s at t = 1.4 s from 750/s at 0.45 s; tests/hard_cases)."""
    return _resolving_step(*fastest_rates(scene, t, q, v))


def _resolving_step(omega: float, rho: float) -> float:
    """:func:`stable_step` from the rates."""
    return min(RESOLVE / omega if omega > 0 else math.inf, 0.5 * RESOLVE / rho if rho > 0 else math.inf)


def step_advice(scene: Any, t: float, q: np.ndarray, v: np.ndarray, h: float) -> str:
    """The words that name a step size resolving the fastest motion at a state
    (:func:`stable_step`), for the messages of a step ``h`` too large for the motion; when
    that estimate is not below ``h`` (the smooth motion is resolved, so contacts closing at
    once or an iterate cap are what failed), they name h/2 instead of a larger step."""
    try:
        hs = stable_step(scene, t, q, v)
    except Exception as exc:  # noqa: BLE001 - the message must not hide the finding
        return f"(no step size estimate: {type(exc).__name__}: {exc}); try h = {h / 2:.2g}"
    if not math.isfinite(hs):
        return f"the model has no fast mode at this state; try h = {h / 2:.2g}"
    if hs < h:
        return (f"a step resolving the fastest motion at this state is about h = {hs:.2g} "
                "(faster motion later may need less)")
    return (f"the fastest smooth motion at this state is resolved (about h = {hs:.2g} would do), so contacts "
            f"closing at once or the cap of iterates are what is too much: try h = {h / 2:.2g}")


def not_converged_message(scene: Any, t: float, q: np.ndarray, v: np.ndarray, h: float, where: str,
                          iterations: int) -> str:
    """The words of an iterating step that did not converge (both paths; ``where`` names
    the step and its time)."""
    return (f"the energy-consistent step did not converge in {iterations} iterations {where} at h = {h:g}: "
            f"the step is too large for this motion; {step_advice(scene, t, q, v, h)}")


def energy_growth_message(scene: Any, t: float, q: np.ndarray, v: np.ndarray, du: float, ke_max: float,
                          h: float) -> str:
    """The words of the energy check (for a warning and for the error that stops a run)."""
    advice = step_advice(scene, t, q, v, h)
    return (f"the energy grew by {du:.3g} beyond the work of the applied forces by t = {t:.6g} "
            f"({du / ke_max:.1%} of the largest kinetic energy so far, {ke_max:.3g}) at h = {h:g}: "
            f"the step is too large for this motion; {advice}")


def runaway_message(scene: Any, t: float, q: np.ndarray, v: np.ndarray, growth: float, h: float) -> str:
    """The words of the energy check's runaway test: the kinetic energy rose above its
    largest so far by ``growth`` a step, at two checks in a row
    (``moreau.compiled.layout.RUNAWAY_RATE``)."""
    return (f"the kinetic energy rose above its largest so far by a factor of {growth:.3g} a step up to t = "
            f"{t:.6g}, at two energy checks in a row, at h = {h:g}: faster than any motion the step resolves (an "
            f"explicit step's runaway, which the work of the applied forces matches); the step is too large for "
            f"this motion; {step_advice(scene, t, q, v, h)}")


def kept_until(message: str, t_kept: float) -> str:
    """The energy stop's message, saying where the kept trajectory ends: at the last check
    that passed (the records after it are the runaway the check stopped)."""
    return (f"{message}; the trajectory is kept up to t = {t_kept:.9g}, the last record at or before the last "
            "energy check that passed")
