"""Newton's law at an impact, located within a step (used by CombinedProjection)."""

from __future__ import annotations

import math

from moreau.core.kernels.jit import jit as _jit

__all__ = ["impact_instant", "impact_law", "newton_target", "NEGLIGIBLE_VELOCITY"]

#: a normal velocity below this (in the scene's unit) is taken as 0 by Newton's law: a
#: closed row at rest with e > 0 otherwise has ``U⁺ = −e U_k`` shrink by e every step, into
#: subnormal numbers after about a thousand steps, whose arithmetic is some 100 times
#: slower (measured: the four-bar resting on its stop at e = 0.5 ran 3x slower per step)
NEGLIGIBLE_VELOCITY = 1e-150


@_jit
def newton_target(e, u):
    """Newton's law ``U⁺ = −e U`` for a closed row with normal velocity ``u`` before the
    step, 0 when ``|u| <`` :data:`NEGLIGIBLE_VELOCITY`."""
    return -e * u if abs(u) >= NEGLIGIBLE_VELOCITY else 0.0


# -- Newton's law at an impact (CombinedProjection) ----------------------------------------
@_jit
def impact_instant(g0, u, an, h):
    """The first s in [0, h] (s) at which ``g0 + u s + an s²/2`` reaches 0: where in the
    step a row that starts at gap ``g0`` (m, or the gap's unit) with normal velocity
    ``u`` and free normal acceleration ``an`` meets its barrier. 0 when it starts inside
    (g0 <= 0), h when the parabola does not reach 0 within the step."""
    if g0 <= 0.0:
        return 0.0
    disc = u * u - 2.0 * an * g0
    if disc < 0.0:
        return h
    d = math.sqrt(disc) - u  # the smaller root as 2 g0 / d: no cancellation
    if d <= 0.0:
        return h
    return min(2.0 * g0 / d, h)


@_jit
def impact_law(e, u, an, g0, h, locate):
    """Newton's law for a row that closes in a step, under CombinedProjection.

    The row bounces when its approach is an impact: faster than the smooth forces change
    its normal velocity in one step. The impulse turns the normal velocity at the impact
    instant s, ``u_s = u + s an``, into ``−e u_s``, and the smooth forces act for the
    rest of the step: ``U⁺ >= −e u_s + (h − s) an``, at least 0 — except with ``locate``
    when that motion keeps the row off the barrier to the end of the step: it may then
    already fall back towards it, and the bound is the motion's own end velocity.

    Parameters
    ----------
    e : float
        Restitution coefficient of the row, > 0.
    u : float
        Normal velocity at the start of the step, ``G(q_m) v_k``.
    an : float
        Free normal acceleration, ``G(q_m) M⁻¹ f``.
    g0 : float
        Gap at the start of the step, ``g(q_k)``.
    h : float
        Step size (s).
    locate : bool
        False: s = h/2 (the step's midpoint, on average where a row that closes in the
        step meets its barrier) and the impact test on ``u``. True: s from
        :func:`impact_instant` and the impact test on ``u_s``.

    Returns
    -------
    c : float
        The lower bound of U⁺ (negative only with ``locate``); NaN when the approach is
        not an impact.
    s : float
        The impact instant (s into the step). The impulse acting at s instead of at the
        midpoint moves the end-of-step position by ``(h/2 − s) M⁻¹ Gᵀ P``, and the
        normal velocities just before and after it sum to ``U + U⁺ + (2 s − h) an``
        (the impact log's energy).
    """
    if locate:
        s = impact_instant(g0, u, an, h)
        us = u + s * an
        fast = -us > abs(h * an)
    else:
        s = 0.5 * h
        us = u + s * an
        fast = -u > abs(h * an)
    if not fast:
        return math.nan, s
    w = h - s
    c = -e * us + w * an
    if not (locate and w * (0.5 * w * an - e * us) > 0.0):  # (the end-of-step gap of that motion)
        c = max(c, 0.0)
    return c, s
