"""The compiled path: the scene lowered to arrays (:mod:`~moreau.compiled.lowering`), its
evaluation (:mod:`~moreau.compiled.evaluate`), user callables behind one C signature
(:mod:`~moreau.compiled.usercalls`), the one time loop (:mod:`~moreau.compiled.loop`, which
runs the schemes of :mod:`moreau.step`), the compile cache (:mod:`~moreau.compiled.cache`) and the driver
that runs the loop chunk by chunk (:mod:`~moreau.compiled.runner`); apart from the loop, the
smooth steps of the tangent dynamics (:mod:`~moreau.compiled.tangent`).

May import: :mod:`moreau.core`, :mod:`moreau.model`, :mod:`moreau.contact`,
:mod:`moreau.results`.
"""

from moreau.compiled.cache import COMPILE_SECONDS, ensure_compiled
from moreau.compiled.runner import COMPILED_SOLVERS, run_compiled

__all__ = ["COMPILED_SOLVERS", "COMPILE_SECONDS", "ensure_compiled", "run_compiled"]
