"""Bundled problems, each built only from moreau's public API.

* :mod:`moreau.problems.bouncing_ball` — a ball on a floor, with the analytic solution;
* :mod:`moreau.problems.pendulum_wall` — a pendulum whose bob hits a vertical wall;
* :mod:`moreau.problems.chain_walls` — a triple pendulum chain falling against three walls;
* :mod:`moreau.problems.piston` — the piston – connecting rod – crankshaft engine of
  Awrejcewicz & Kudra;
* :mod:`moreau.problems.woodpecker` — the woodpecker toy of Pfeiffer & Glocker (friction
  and impacts);
* :mod:`moreau.problems.four_bar` — a four-bar linkage, a closed loop held by bilateral
  constraints, with an optional stop.
"""
