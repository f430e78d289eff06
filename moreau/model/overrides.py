"""Which compiled kernel stands for a model part: its own, unless the user replaced a method
the kernel computes.

A built-in part (:class:`~moreau.ConstantForce`, :class:`~moreau.LinearBarrier`, a chain, ...)
hands the compiled loop a kernel (``kernel()``, ``tangent_kernel()``, ``mass_kernel()``) that
computes what its Python methods do. A subclass that overrides one of those methods (a
``ConstantForce`` whose ``force`` grows with t), or an instance given one of its own, changes
what the part means; the kernel would not see it. Such a part is the user's: the loop calls
its Python methods (compiled where numba can), as for any part without a kernel.
"""

from __future__ import annotations

from typing import Any

__all__ = ["kernel_of", "users"]

#: the Python methods each kernel method stands for (``kernel``: by the kind of part)
_COMPUTES = {"mass_kernel": ("mass_matrix", "bias_force"), "tangent_kernel": ("tangent_jacobian",)}
_BARRIER, _EFFECT = ("gap", "jacobian"), ("force", "potential")


def kernel_of(part: Any, method: str = "kernel") -> Any:
    """``part.<method>()`` — ``(kind, params)``, ``("user", ...)`` or None — or None when a
    subclass below the class that defines ``method``, or the instance itself (with anything
    but a method bound to it), overrides a method that kernel computes (then the part runs
    through its Python methods)."""
    spec = getattr(part, method)()
    if users(spec):
        return spec
    computes = _COMPUTES.get(method) or (_BARRIER if hasattr(part, "gap") else _EFFECT)
    for cls in type(part).__mro__:
        if method in vars(cls):  # the kernel's own class: its methods are the kernel's
            break
        if any(name in vars(cls) for name in computes):
            return None
    own = getattr(part, "__dict__", None) or {}
    for name in computes:  # (a method of its own class bound at its construction, as PointForce's, is the kernel's)
        f = own.get(name)
        if f is not None and getattr(f, "__self__", None) is not part:
            return None
    return spec


def users(spec: Any) -> bool:
    """True for the part of a :func:`kernel_of` answer the user gives (None or
    ``("user", ...)``): checked at a run's start; False for a built-in one, checked when built."""
    return spec is None or spec[0] == "user"
