"""The compiled loop's data layout (status codes, indices into its settings, counters,
accumulators, per-row state and impact log) and the numba options of its parts."""

from collections import namedtuple

from numba import njit

# the lowered scene's ints (moreau.compiled.lowering.CompiledScene.ints): coordinates n, rows
# m, the mass matrix's kernel kind, has bias terms, its pool offset, effects, contacts,
# velocity-dependent forces, some kernel uses cos q / sin q, tangent rows mf (friction),
# bilateral rows me, the first bilateral barrier record
(SC_N, SC_M, SC_MASS_KIND, SC_HAS_BIAS, SC_MASS_OFF, SC_N_EFFECTS, SC_N_CONTACTS, SC_VELOCITY_DEPENDENT, SC_TRIG,
 SC_MF, SC_ME, SC_FIRST_EQ) = range(12)
# status codes
DONE, IMPACTS_FULL, SOLVER_FAILED, NONFINITE, NOT_SPD, NONFINITE_GAP, USER_FAILED, ENERGY_GROWTH = range(8)
# (bilateral rows: inconsistent at a step, or not held by the position projection)
CONSTRAINTS_INCONSISTENT, CONSTRAINTS_NOT_HELD = 8, 9
# (the energy-consistent step's iteration did not converge)
NOT_CONVERGED = 10
# (drift control's position projection: its contact solve failed, main and fallback)
PROJECTION_FAILED = 11
# (step-size control: the record buffers are full; the runner grows them and calls again)
RECORDS_FULL = 12
# (a function called through its address was made for other argument types: moreau's own bug)
NATIVE_MISMATCH = 13
# (step-size control's attempt goes on with its next step: never a chunk's status)
STEP_ON = -1
# settings (int array)
S_STEP, S_DRIFT, S_DRIFT_ITER, S_STRIDE, S_NSTEPS, S_METHOD, S_FALLBACK, S_ENERGY, S_MEMORY, S_LOCATE = range(10)
# (S_ECHECK: the energy check's interval in steps, 0 = off; see moreau.run.energy)
S_ECHECK = 10
# (S_ITER: iterates allowed per energy-consistent step)
S_ITER = 11
# (S_EXTERNAL, S_EXTERNAL + 1: the addresses of the main and the fallback solver where their
# method is METHOD_EXTERNAL, a solver called back in Python: compiled.callbacks.SolverCallback)
S_EXTERNAL = 12
# (S_RECORD: with step-size control, record every this many accepted steps; the steps'
# own S_STRIDE and S_NSTEPS then never record)
S_RECORD = 14
# (S_MASS_READY: 1 once a constant M and its factor are in the run's work arrays: step-size
# control sets it after its first step, so its chunks do not form and factor M again; 0 for
# fixed steps, whose chunks form it once each)
S_MASS_READY = 15
# (S_DRIFT_VELOCITY: 1 when drift control also makes the velocity of the rows it held
# admissible at q⁺, G(q⁺) v⁺ >= 0: PositionProjection(velocity=True))
S_DRIFT_VELOCITY = 16
# (S_PROJECT, S_PROJECT_KEY: the address of the drift projection's machine code for the run's
# argument types, and the key of those types: compiled.drift.projection_address)
S_PROJECT, S_PROJECT_KEY = 17, 18
# (S_FRICTION, S_FRICTION_KEY: the same for the friction solve, compiled.friction.friction_address)
S_FRICTION, S_FRICTION_KEY = 19, 20
# (S_WARM, S_WARM_KEY, S_DELASSUS, S_DELASSUS_KEY: the same for a chain's warm start and its
# Delassus matrix, compiled.step.warm_start_addresses)
S_WARM, S_WARM_KEY, S_DELASSUS, S_DELASSUS_KEY = 21, 22, 23, 24
# (S_JUDGE, S_JUDGE_KEY: the same for step-size control's judge of an attempt, compiled.adaptive.judge_address)
S_JUDGE, S_JUDGE_KEY = 25, 26
N_SETTINGS = 27
# the LCP methods (S_METHOD, S_FALLBACK): dual active set, enumeration, called back; -1 none
METHOD_EXACT, METHOD_ENUM, METHOD_EXTERNAL = 0, 1, 2
# the step (S_STEP): midpoint, predictor-corrector, energy-consistent
STEP_MIDPOINT, STEP_THETA, STEP_ENERGY = 0, 1, 2
# drift control modes (S_DRIFT)
DRIFT_NONE, DRIFT_POSITION, DRIFT_COMBINED = 0, 1, 2
# per-row state of CombinedProjection (float array (m, N_ROWSTATE)): gap at q_k, the gap where
# the projection last held the row, held (pinned), restitution applied in this step, for
# a row that bounced at s into the step h/2 − s and (2 s − h) a_n (kernels.impact_law), and
# the gap at q⁺ before drift control moved it (stored under drift control only: without it,
# R_GAP; step-size control's crossing rule)
R_GAP, R_PINGAP, R_PINNED, R_BOUNCED, R_DELAY, R_SHIFT, R_UNPROJECTED = range(7)
N_ROWSTATE = 7
# impact-log columns (I_CROSS: the time the row's gap crossed zero in the step, estimated)
I_T, I_STEP, I_ROW, I_UB, I_UA, I_P, I_LOST, I_FLIGHT, I_FAST, I_CROSS = range(10)
N_IMPACT = 10
# settings (float array)
F_H, F_T0, F_TOL, F_DRIFT_TOL, F_PE0, F_EWARN, F_ESTOP = range(7)
# (F_ITOL: the energy-consistent step's iteration tolerance)
F_ITOL = 7
# counters (int array)
# (C_USER: the status of a user callable that failed, see moreau.compiled.usercalls.decode)
# (C_EWARN: the step at which the energy check first warned, 0 = never; C_ELEVEL: the
# bound the last check found passed, 0 none, 1 warn, 2 stop)
# (C_PAINLEVE: steps with a sliding contact in Painlevé's region; C_PAINLEVE_STEP: the first
# one's step index + 1, 0 = never; C_PAINLEVE_ROW: its first such row)
C_REC, C_NIMP, C_SOLVES, C_FALLBACKS, C_CONTACT, C_PROJ, C_K, C_FAILKIND, C_USER, C_EWARN, C_ELEVEL = range(11)
C_PAINLEVE, C_PAINLEVE_STEP, C_PAINLEVE_ROW = 11, 12, 13
# (C_EQROW: the bilateral row named by a CONSTRAINTS_* status)
C_EQROW = 14
# (C_UPDATES: velocity updates computed, one per pass: see SolverStats.velocity_updates)
C_UPDATES = 15
# (C_EOK: the step of the last energy check that passed, below both bounds: a run the check
# stops is kept up to it)
C_EOK = 16
# (step-size control, moreau.compiled.adaptive: steps accepted, attempts rejected, steps
# accepted at the smallest step above the tolerance)
C_ACCEPTED, C_REJECTED, C_FORCED = 17, 18, 19
# (the energy check's runaway test: the step of its last check, and how many checks in a row
# found the kinetic energy growing beyond its largest so far faster than a resolved motion can)
C_KLAST, C_RUNAWAY = 20, 21
N_COUNTERS = 22
# accumulators (float array)
# (the energy check: kinetic energy at the start, the largest so far, the unaccounted energy
# at the warning and at the last check, the work of the bias terms)
# (A_WORK_T: the work of the friction impulses)
A_WORST, A_WORK_F, A_WORK_C, A_KE0, A_KEMAX, A_DU_WARN, A_DU, A_WORK_B, A_WORK_T = range(9)
# (A_WORK_E: the work of the bilateral rows' impulses; A_EQRES: the largest |g_E| the
# position projection left; A_WORK_EV: the kinetic energy the velocity projection onto the
# bilateral rows removed)
A_WORK_E, A_EQRES, A_WORK_EV = 9, 10, 11
# (A_KEMAX_WARN: the largest kinetic energy when the energy check first warned, which the
# warning quotes)
A_KEMAX_WARN = 12
# (the times the energy check first warned and Painlevé's region was first met: t0 + k h on
# fixed steps, the adaptive step's own time with step-size control)
A_T_EWARN, A_T_PAINLEVE = 13, 14
# (A_RUNAWAY: the growth factor a step that stopped a run as a runaway, 0 otherwise)
A_RUNAWAY = 15
N_ACCUMULATORS = 16
#: the runaway test's bound: a kinetic energy above the largest so far by more than
#: exp(RUNAWAY_RATE) a step since the last check (an amplitude growing by more than a fifth a
#: step), at two checks in a row, is a motion the step does not resolve
RUNAWAY_RATE = 0.4
# step-size control's state (float array): the step to try next, the time reached, the end
# time, the relative tolerance (the absolute ones: Snapshot.atol), the largest and smallest step, the start of the
# step of the last energy check that passed, the last accepted step, its scaled error and kind,
# and the largest error constant (scaled error / H^(order+1)) of the smooth steps in the time
# window of the largest step that holds the current time and in the one before, and the start
# of the current window
K_H, K_T, K_END, K_RTOL, K_HMAX, K_HMIN, K_TOK, K_HACC, K_EACC, K_KACC, K_C0, K_C1, K_CB = range(13)
N_CONTROL = 13

# The step's parts are inlined into the loop by numba (IR level), as are the evaluation
# functions (moreau.compiled.evaluate); the kernels and LCP routines they call are inlined by LLVM
# (forceinline) and compiled once each. Measured (benchmarks/compile_cost.py, and the
# piston at e = 0.9 against the former build, best of 3-4 interleaved runs): numba
# inlining at every level compiled for 7-10 min in 10.8 GB; LLVM inlining at every level
# compiles in ~30 s but the step costs 8 % more; the kernels as plain calls 26 % more, and
# the parts too (their tuples of arrays passed at every call) 38 % more. No CPython or C
# entry points are built for what only the loop calls.
part = njit(cache=True, nogil=True, _nrt=False, inline="always",  # type: ignore[call-overload]
            no_cpython_wrapper=True, no_cfunc_wrapper=True)
# What runs in few steps (the drift projection when a row penetrates, the energy check) is
# a call instead: typed and lowered once, apart from the loop, it keeps its body out of the
# loop function (benchmarks/compile_cost.py: the loop function itself 73.5 -> 55.1 s cold,
# the drift projection 7.7 s apart; the piston step unchanged within noise). Its optimized
# code is still linked into the loop's module, whose second LLVM pass over it is cheap
# (docs/performance.md: called through an address instead, no faster). Tried: the
# model evaluations (moreau.compiled.evaluate) as calls: the loop 47.8 s, but the piston
# step 10-12 % slower (their call sites run every step).
call = njit(cache=True, nogil=True, _nrt=False,  # type: ignore[call-overload]
            no_cpython_wrapper=True, no_cfunc_wrapper=True)


# The arguments of run_chunk, by name (it hands their fields to the compiled _run_chunk).
#: the run's settings: the int and float settings above, M⁻¹ of a constant M, the rows drift
#: control may move (m,), each row's flight gap (m,)
Settings = namedtuple("Settings", "iset fset Minv eligible fgap")
#: the state a chunk resumes from: q, v (n,); per row (m,): in contact, the impulse and activity
#: summed since the last record, the step of its last impulse, its largest gap since then; the
#: per-row state of CombinedProjection (m, N_ROWSTATE); the deepest penetration and its step (2, m)
RunState = namedtuple("RunState", "q v in_contact P_acc act_acc last_imp gmax rs pen")
#: the record buffers: times, states, impulses, activity, gaps, energies, the impact log,
#: the tangential impulses of a scene with friction
Records = namedtuple("Records", "T Q V PS ACT GP KE PE IMP PTS")
#: the counters, accumulators and the failed solves' residuals (see above)
Tally = namedtuple("Tally", "cnt acc fail")
#: friction's work arrays (compiled.friction.friction_work): per active row its index among the
#: normal rows and its mu; per row the step's tangential impulse and its sum since the last
#: record; the law residuals (6,); Lemke's work arrays; per row its mu and tangent row
FrictionWork = namedtuple("FrictionWork", "fidx muA PT PT_acc res lemke mu tangent_row")
#: the bilateral rows' work arrays (compiled.bilateral.equality_work): their basis (Q, R, piv),
#: the reduced problem's vectors (x, y, by), impulses PE and F, the identity, yv, the impulses
#: summed since the last record, cE, the rank (1,), and the velocity projection's rows S
EqualityWork = namedtuple("EqualityWork", "Q R piv x y by PE F eye yv PE_acc cE rank S")
#: the step's own work arrays (compiled.variants.loop_workspace): M(q_m) and its factor, cos/sin
#: of q_m and of q⁺, q_m, the forces, v⁺, a spare vector, q⁺, the gaps at q_m and at q⁺,
#: the impulses and closed rows, the Jacobian (all rows), the free velocity, the bias forces
StepWork = namedtuple("StepWork", "M L cm sm cq sq qm f v_new vbar q_new gm gq P active G vfree fb")
#: the contact problem's work arrays: the closed rows' Jacobian and targets, the free
#: acceleration, M v + h f, the closed rows' impulses, the drift projection's Jacobian, step
#: and zero vector, its rows, a chain's factor generators (4, n), and q, v where the energy
#: check first warned
LoopWork = namedtuple("LoopWork", "GA cA rhs b PA G dq zero sel gen q_warn v_warn held")
#: the later passes' work arrays (compiled.implicit): M(q_k), cos/sin of q_k, q at the pass,
#: Δq, the iterate x, the last answer and residual (Anderson mixing), a chain's M_m v_k, and
#: the forces that do not depend on v
PassWork = namedtuple("PassWork", "Ms c2 s2 qp dq x ylast rlast mv fq")
#: step-size control's snapshot of a step's start (restored when an attempt is rejected: the
#: run state, counters, accumulators and friction's and the bilateral rows' sums since the last
#: record), the coarse step's end (q, v, gaps), the closed rows of the step before, of the coarse
#: and of the first fine step, each row's time of its deepest penetration, and with friction
#: each row's slip (0 sticking or open, ±1 the sign of its tangential impulse when it slides)
#: at the end of the last accepted step, of the coarse and of the first fine step, the first
#: fine step's normal and tangential impulses per row, a spare vector (n), and the coarse
#: step's end gaps before drift control moved them; and the absolute tolerance of each
#: component of (q, v) (2 n)
Snapshot = namedtuple("Snapshot", "q v in_contact P_acc act_acc last_imp gmax rs pen cnt acc PT_acc PE_acc "
                      "qc vc gc closed0 closed_c closed_f pen_t slip0 slip_c slip_f p_f pt_f x gu atol")
#: the lowered scene's arrays (compiled.lowering.CompiledScene.arrays): the int settings, the
#: effects' kinds and offsets, the barriers' kinds, offsets, first rows and row counts, the
#: parameter pool, each row's restitution and activation tolerance
ModelArrays = namedtuple("ModelArrays", "ints ekind eoff bkind boff brow bnrows pool e atol")


def chunk_arguments(model: tuple, user, settings: Settings, state: RunState, records: Records, tally: Tally,
                    work: tuple, k_end: int) -> tuple:
    """The arguments of the compiled ``loop._run_chunk``: the fields of ``loop.run_chunk``'s
    named tuples (the kernel is faster on separate arrays), the features' work arrays apart
    (numba prunes on their being None)."""
    st, rec = state, records
    own, ws, lw, fr, eqw, ec = work
    return (model, user, settings.iset, settings.fset, settings.Minv, settings.eligible, st.q, st.v, k_end,
            st.in_contact, st.P_acc, st.act_acc, rec.T, rec.Q, rec.V, rec.PS, rec.ACT, rec.GP, rec.KE, rec.PE,
            rec.IMP, st.pen, tally.cnt, tally.acc, tally.fail, st.last_imp, st.gmax, settings.fgap, st.rs,
            (own, ws, lw), rec.PTS, fr, eqw, ec)
