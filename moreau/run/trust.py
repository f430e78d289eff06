"""Run-level checks of :func:`moreau.simulate`: what a step's own checks cannot see.

* Before the run, every barrier's analytic Jacobian (contacts and bilateral constraints) is
  compared with central finite differences of its gap at the initial state, a user's also a
  little off it: a Jacobian of the wrong sign or scale would otherwise let the contact
  drift through the barrier and the run "complete". A
  user system's bias force is compared with the velocity-squared terms of its mass matrix
  (:func:`moreau.model.system.check_bias`): a wrong sign there would otherwise show only as
  energy growing at every h.
* After the run, the largest penetration of every row over every step is compared with a
  limit: the scheme's own scale ``h·|U⁻|`` (the distance a contact approaching at the normal
  speed U⁻ of its impacts travels in one step) unless the caller gives one (the piston
  passes its clearance). A row that penetrated without ever carrying an impulse was never
  enforced (a Jacobian that vanishes near the barrier, say): it warns beyond its
  activation tolerance, the penetration the run accepted of its initial state and the
  largest ``h·|U⁻|`` of the run's impacts (a row redundant with one that carried the
  impulse penetrates as deep as that one); one that crossed the barrier in the run's last
  step says so instead; a penetration deepest in contact, away from the row's impacts, in
  a run without drift control, is named as the drift of a persistent contact. A run
  beyond it warns once and records the warning in ``traj.warnings``, which
  ``save``/``load`` keep.
"""

from __future__ import annotations

import warnings

import numpy as np

from moreau.contact.equality import eq_basis
from moreau.model.barriers import finite_difference_jacobian, near_point
from moreau.model.overrides import kernel_of, users
from moreau.model.system import check_bias
from moreau.step.checks import START_PENETRATION_TOL

__all__ = ["check_bias_force", "check_jacobians", "constraint_rank", "penetration_warnings", "redundancy_warnings"]


def check_jacobians(scene, q0: np.ndarray, rtol: float = 1e-5) -> None:
    """Raise ``ValueError`` naming the contact or bilateral constraint row of a user's
    barrier (one without a kernel of moreau's own) whose analytic Jacobian differs from
    central finite differences of its gap at ``q0``, or a little off it
    (:func:`~moreau.model.barriers.near_point`), by more than ``rtol`` (relative to the
    row's largest entry; an absolute floor of 1e-8 for rows that vanish there). A built-in
    barrier's Jacobian is its kernel's, tested against finite differences at random
    states in ``tests/test_chain.py``: a run does not pay for checking it again.

    The differences are taken with steps relative to ``|q0|`` and, where that fails, with
    absolute steps of 1e-6: a crank angle of thousands of radians makes the relative step
    too coarse for a gap that varies on the scale of one radian (a false alarm)."""
    groups = [(c.barrier, c.barrier.row_names(c.name), "contact row") for c in scene.contacts]
    groups += [(e.geometry, e.row_names(), "constraint row") for e in scene.constraints]
    first = {"contact row": 0, "constraint row": 0}  # each group's first row in its own numbering
    for b, names, kind in groups:
        row = first[kind]
        first[kind] += b.nrows
        if users(kernel_of(b)):  # a built-in barrier's own Jacobian is tested
            _check_rows(b, q0, b.jacobian(q0), names, row, rtol, "at the initial state", kind)
            qc = near_point(q0)
            try:
                Gc = b.jacobian(qc)
            except Exception:  # noqa: BLE001 - a barrier undefined off q0: the run says where it fails
                Gc = None
            if Gc is not None:
                _check_rows(b, qc, Gc, names, row, rtol, f"near the initial state (at q = {_short(qc)})", kind)


def _check_rows(b, q: np.ndarray, G, names: list[str], row: int, rtol: float, where: str, kind: str) -> None:
    """:func:`check_jacobians` for one barrier (``kind``: its rows' word) at one point, ``G``
    its analytic Jacobian there."""
    G = np.atleast_2d(np.asarray(G, dtype=float))
    relative = finite_difference_jacobian(b.gap, q)
    absolute = None  # the differences with absolute steps, taken where the relative ones fail
    for r in range(b.nrows):
        Gfd = relative
        err, scale = _mismatch(G[r], Gfd[r])
        if err > rtol * scale and err > 1e-8:
            if absolute is None:
                absolute = finite_difference_jacobian(b.gap, q, relative=False)
            err_a, scale_a = _mismatch(G[r], absolute[r])
            if err_a / scale_a < err / scale:
                err, scale, Gfd = err_a, scale_a, absolute
        if err > rtol * scale and err > 1e-8:
            raise ValueError(
                f"the Jacobian of {kind} {names[r]!r} (row {row + r}) does not match its gap {where}: "
                f"analytic {G[r].tolist()}, finite differences {Gfd[r].tolist()} (relative error "
                f"{err / scale:.3g}); fix the Jacobian, or pass check_jacobian=False for a gap that is not "
                "differentiable there")


def check_bias_force(scene, q0: np.ndarray, rtol: float = 1e-5) -> None:
    """Raise ``ValueError`` when the bias force of a scene's own system (not a built-in
    chain's) differs from ``−Ṁ v + ½ ∇_q(vᵀ M v)`` of its mass matrix by more than ``rtol``
    near ``q0`` (:func:`~moreau.model.system.check_bias`; zero for a constant M), or when
    M depends on q and the system has no bias force."""
    system = scene.system
    if (system.constant_mass and not system.has_bias) or not users(kernel_of(system, "mass_kernel")):
        return  # nothing to compare, or a built-in system's own (tested) terms
    c = check_bias(system, q0)
    if c.ok(rtol):
        return
    name = getattr(system, "name", type(system).__name__)
    at = (f"at q = {_short(c.q)}, v = {_short(c.v)} the velocity-squared terms of M(q), −Ṁv + ½∇(vᵀMv) by finite "
          f"differences, are {_short(c.numeric)}")
    if not system.has_bias:
        raise ValueError(f"the mass matrix of system {name!r} depends on q but the system has no bias force: {at}; "
                         "give them as bias= (FunctionSystem) or bias_force (MechanicalSystem, with has_bias = True), "
                         "or pass check_jacobian=False to run without them")
    raise ValueError(f"the bias force of system {name!r} does not match its mass matrix: {at}, bias_force gives "
                     f"{_short(c.analytic)} (relative error {c.max_rel_error:.3g}); it stands on the right-hand side, "
                     "M dv/dt = bias + forces, and other velocity-dependent forces belong in an effect "
                     "(FunctionForce); pass check_jacobian=False to skip this check")


def _short(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{float(e):.6g}" for e in x) + "]"


def _mismatch(g: np.ndarray, g_fd: np.ndarray) -> tuple[float, float]:
    """The largest difference of an analytic Jacobian row and its finite differences, and
    the row's scale (its largest entry, or theirs)."""
    return float(np.abs(g - g_fd).max()), max(float(np.abs(g).max()), float(np.abs(g_fd).max()), 1e-300)


def penetration_warnings(scene, traj, h: float, limit: float | None,
                         initial_penetration: float = START_PENETRATION_TOL, drift_control=None) -> list[str]:
    """Rows whose largest penetration over every step exceeds its limit (see the module
    docstring), as messages; also issued once as a ``RuntimeWarning``.
    ``initial_penetration``: what the run accepted of its initial state (gap units);
    ``drift_control``: the run's (None: a penetration deepest in contact, away from the
    row's impacts, is named as the drift it is)."""
    pen = traj.max_penetration
    if pen is None or not (pen > 0.0).any():
        return []
    out: list[str] = []
    n_rec = len(traj)
    carried = np.asarray(traj.impulses).sum(axis=0) > 0.0 if n_rec else np.zeros(len(pen), dtype=bool)
    when = traj.max_penetration_t if traj.max_penetration_t is not None else np.full(len(pen), np.nan)
    onsets = traj.onsets  # its impacts (``traj.impacts``): the fast onsets after a flight
    is_impact = onsets.flight & onsets.fast
    U_imp, row_imp, t_imp_all = np.abs(onsets.U_before[is_impact]), onsets.row[is_impact], onsets.t[is_impact]
    tol, scene_scale = None, 0.0  # for the rows never enforced, computed at the first that penetrated

    def at(r: int | np.integer) -> str:  # the time of the row's deepest penetration, when the run kept it
        return f" at t = {when[r]:.9g} s" if np.isfinite(when[r]) else ""

    for r in np.flatnonzero(pen > 0.0):
        if limit is not None:
            lim, why = float(limit), "the given limit"
        elif not carried[r]:  # never an impulse: the row was never enforced (a vanishing Jacobian?), unless
            # it penetrated no deeper than the scene's impacts may (a row whose twin carried the impulse, say)
            if tol is None:  # round-off: the row's activation tolerance, or its gap's round-off over the run
                gap_size = np.nanmax(np.abs(traj.gaps), axis=0, initial=0.0) if n_rec else np.zeros(len(pen))
                tol = np.maximum(np.asarray(getattr(scene, "activation_tol", np.zeros(len(pen))), dtype=float),
                                 8.0 * np.finfo(float).eps * gap_size)
                scene_scale = h * float(U_imp.max()) if U_imp.size else 0.0  # the deepest h·|U⁻| of any impact
            if pen[r] > max(tol[r], scene_scale, initial_penetration):
                if _crossed_at_the_end(scene, traj, r, h, pen[r], when[r]):
                    why = ("in the run's last step, before a step could close its contact: the final state penetrates "
                           "(run on, or take a smaller h)")
                else:
                    why = ("without any contact impulse: the contact was never enforced (does its Jacobian vanish "
                           "there?)")
                out.append(f"row {traj.row_names[r]!r} penetrated {pen[r]:.3g} (gap units){at(r)} {why}")
            continue
        else:
            U = U_imp[row_imp == r]
            if U.size == 0:
                continue  # no impact: the drift of a sliding contact, left to drift control
            U_max = float(U.max())
            lim, why = h * U_max, f"h·|U⁻| = {h:g} × {U_max:.3g}, the step's own scale"
        if pen[r] > lim:
            t_imp = t_imp_all[row_imp == r]
            away = float(np.min(np.abs(t_imp - when[r]), initial=np.inf))
            cause = "the contact is not resolved at this step size"
            if drift_control is None and carried[r] and away > 2.0 * h:  # deepest in contact, not at an impact
                cause = (f"deepest {away:.3g} s from its impacts" if t_imp.size else "with no impact") + \
                        (", in contact: the drift of a persistent contact, which drift control holds "
                         "(drift_control=mo.CombinedProjection()) and a smaller h reduces")
            out.append(f"row {traj.row_names[r]!r} penetrated {pen[r]:.3g} (gap units){at(r)}, beyond {why} "
                       f"({lim:.3g}): {cause}")
    if out:
        warnings.warn("; ".join(out), RuntimeWarning, stacklevel=3)
    return out


def _crossed_at_the_end(scene, traj, r, h: float, pen: float, when: float) -> bool:
    """Row ``r`` reached its deepest penetration ``pen`` at the run's end, no deeper than
    the last step's travel at the final normal speed: it crossed in the last step, and no
    step was left to close its contact."""
    if not len(traj) or not abs(when - traj.t[-1]) <= 0.5 * h:
        return False
    G = np.atleast_2d(np.asarray(scene.jacobian(traj.q[-1]), dtype=float))
    return pen <= h * abs(float(G[r] @ traj.v[-1]))


def redundancy_warnings(scene, q0) -> list[str]:
    """Contact rows with friction whose normal direction the bilateral rows already hold at
    ``q0`` (G_r in the span of the rows of G_E), as messages; also issued once as a
    ``RuntimeWarning``. The normal load is then split between redundant rows in a way the
    model does not determine, and the friction it allows may be any part of mu times it, or
    none: a rail and a rough floor on the same coordinate, say."""
    if not getattr(scene, "nconstraints", 0) or not scene.has_friction:
        return []
    q = np.asarray(q0, dtype=float)
    if q.shape != (scene.ndof,) or not np.all(np.isfinite(q)):
        return []  # the run's own checks name a bad initial state
    GE = np.vstack([np.atleast_2d(np.asarray(bc.geometry.jacobian(q), dtype=float)) for bc in scene.constraints])
    G = np.atleast_2d(np.asarray(scene.jacobian(q), dtype=float))
    out = []
    for r in np.flatnonzero(np.asarray(scene.friction) > 0.0):
        norm = float(np.linalg.norm(G[r]))
        if norm == 0.0:
            continue
        coef = np.linalg.lstsq(GE.T, G[r], rcond=None)[0]
        if np.linalg.norm(GE.T @ coef - G[r]) <= 1e-9 * norm:
            held = [scene.constraint_names[i] for i in np.flatnonzero(np.abs(coef) > 1e-9 * np.abs(coef).max())]
            out.append(f"contact row {scene.row_names[r]!r} (mu = {float(scene.friction[r]):g}) is redundant with the "
                       f"bilateral rows {held} at the initial state: they hold its normal direction, so how the "
                       "normal load splits between them is not determined, and the friction on it may act on a "
                       "part of that load or on none")
    if out:
        warnings.warn("; ".join(out), RuntimeWarning, stacklevel=3)
    return out


def constraint_rank(scene, q) -> tuple[int, list[str]]:
    """``(rank, redundant)``: the rank of the scene's bilateral rows at q and the names of
    the rows the step's pivoted QR finds redundant (dependent on the others: they keep v
    unique and carry zero impulse)."""
    if not scene.nconstraints:
        return 0, []
    n, me = scene.ndof, scene.nconstraints
    q = np.asarray(q, dtype=float)
    L = np.linalg.cholesky(np.asarray(scene.system.mass_matrix(q), dtype=float))
    G = np.ascontiguousarray(scene.constraint_jacobian(q), dtype=float)
    piv = np.zeros(me, dtype=np.int64)
    rank = eq_basis(L, G, 0, me, np.empty((n, n)), np.empty((n, me)), piv, np.empty(n))
    return int(rank), [scene.constraint_names[i] for i in piv[rank:]]
