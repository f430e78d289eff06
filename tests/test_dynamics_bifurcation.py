"""Bifurcation diagrams on moreau.sweeps: sections per parameter, exponent, resumable."""

from __future__ import annotations

import functools

import numpy as np

from moreau.dynamics import bifurcation, bifurcation_diagram
from moreau.dynamics.benchmarks import table_period1, vibrating_table


def test_bifurcation_diagram_of_the_vibrating_table_is_resumable(tmp_path, monkeypatch):
    """Two amplitudes of the ball on the table (e = 0.5): at A = 1.49 the period-1 orbit
    (one impact per period, negative exponent ≈ ln 0.836 / 2π = -0.0286), at A = 1.6 past
    its period-doubling (|trace J| > 1 + det J: two section values alternate). Run twice
    into the same table: the second run reads every point back."""
    orb = table_period1(0.5, 1.49)
    tau = 2 * np.pi - orb.phi  # the orbit's state at t = 0, a flight time tau after its impact
    z0 = np.pi * tau - tau ** 2 / 2 + 1.49 * np.sin(orb.phi)
    out = tmp_path / "table.csv"
    kw = dict(q0=[z0], v0=[np.pi - tau - 1.49], h=orb.T / 1000, period=orb.T, n_transient=20,
              n_points=8, components=(0, 1), phase_time=0.0,
              lyapunov=dict(n_intervals=12, n_align=4, d0=0.1), executor="serial", out=out, progress=False)
    make = functools.partial(vibrating_table, 0.5)
    df = bifurcation_diagram(make, "A", [1.49, 1.6], **kw)
    assert list(df["A"]) == [1.49, 1.6] and df["error"].isna().all()
    sec = np.asarray(df["section"][0])
    assert sec.shape == (8, 2)
    assert df["n_impacts"][0] == 8
    assert -0.04 < df["lyapunov"][0] < -0.02
    two = np.asarray(df["section"][1])[:, 0]
    assert abs(two[0] - two[1]) > 10 * abs(two[0] - two[2])  # period 2 on the section
    computed = []  # the second run computes no point (a timed bound here failed under load)
    point = bifurcation.bifurcation_point
    monkeypatch.setattr(bifurcation, "bifurcation_point", lambda **a: computed.append(a) or point(**a))
    again = bifurcation_diagram(make, "A", [1.49, 1.6], **kw)
    assert computed == []
    assert np.allclose(np.asarray(again["section"][1]), np.asarray(df["section"][1]))
