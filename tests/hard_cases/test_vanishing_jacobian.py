"""A closed row whose Jacobian vanishes cannot carry an impulse: the step goes on without
one (both paths), never a ZeroDivisionError from the residual check."""

import numpy as np
import oracle
import pytest

import moreau as mo
from moreau.model.chain import ChainGravity, Link, PendulumChain, PointLineBarrier, PointLineRow


def tangent_pendulum():
    """A rod hanging from the origin, its tip touching the floor y = -1 at the bottom of its
    swing, where the tip's height does not change with the angle (G = l sin φ = 0)."""
    chain = PendulumChain([Link.rod(m=1.0, l=1.0)])
    rows = [PointLineRow(0, (1.0, 0.0), line_point=(0.0, -1.0), normal=(0.0, 1.0))]
    return mo.Scene(chain, [ChainGravity(chain)], [mo.Contact(PointLineBarrier(chain, rows), 0.0, name="floor")])


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_pendulum_tip_touching_the_floor_tangentially_completes(backend):
    scene = tangent_pendulum()
    at_rest = oracle.simulate(scene, (0.0, 0.5), [0.0], [0.0], 1e-3, backend=backend, solver="exact")
    assert at_rest.completed and at_rest.stats.contact_steps > 0  # the row closes every step
    np.testing.assert_array_equal(at_rest.impulses, 0.0)  # and carries nothing
    np.testing.assert_array_equal(at_rest.q, 0.0)  # the pendulum stays where it is
    swinging = oracle.simulate(scene, (0.0, 2.0), [0.3], [0.0], 1e-3, backend=backend, solver="exact")
    assert swinging.completed
    assert np.all(swinging.gaps >= -1e-9)
