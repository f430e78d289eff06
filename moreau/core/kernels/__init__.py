"""Physics kernels: the one implementation of every built-in mass matrix, force and gap.

Each kernel is a small numba function on arrays, free of allocation where it writes into
``out``: the compiled time loop (:mod:`moreau.compiled.loop`) calls them step after step, and
Python calls the very same functions through the objects of :mod:`moreau.model.forces`,
:mod:`moreau.model.chain` and :mod:`moreau.model.barriers` (so the physics is written once). Kernels
that *add* into ``out`` accumulate a sum of effects without temporaries.

Parameters are read from one flat float array at an offset (the layout is stated per
kernel): a scene's parameters live in one pool, and the hot loop creates no array views.

Kinds (the codes a scene is lowered to, :mod:`moreau.compiled.lowering`):

========== ===================================================== ========================
code       generalized force added                               built from
========== ===================================================== ========================
CONST      ``c``                                                 ConstantForce, LinkTorque
LINEAR_V   ``−C v``                                              LinearDamping, JointDamping
AFFINE_Q   ``−K q + b``                                          LinearSpring, JointSprings
TRIG       ``B ∘ cos q − A ∘ sin q``                             ChainGravity, PointForce
HARMONIC   ``a sin(ω t + φ)``                                    HarmonicForce
FOURIER_PT ``cos q ∘ (X F) + sin q ∘ (Y F)``, F = d·s(q_j)       PointForce(FourierLoad)
========== ===================================================== ========================

Barriers: LINEAR ``g = A q + b`` (LinearBarrier, JointStop) and TRIG
``g = g0 + A cos q + B sin q`` (PointLineBarrier). Masses: constant, or the pendulum
chain's ``ν ∘ cos(φ_i − φ_j) + ν^s ∘ sin(φ_i − φ_j)``.
"""

from moreau.core.kernels.chain import *  # noqa: F403
from moreau.core.kernels.codes import *  # noqa: F403
from moreau.core.kernels.forces import *  # noqa: F403
from moreau.core.kernels.gaps import *  # noqa: F403
from moreau.core.kernels.impact import *  # noqa: F403
from moreau.core.kernels.jit import jit as _jit  # noqa: F401 - first: checks the compile cache
from moreau.core.kernels.linalg import *  # noqa: F403
from moreau.core.kernels.wrappers import *  # noqa: F403
