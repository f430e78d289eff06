# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Piston slap against the restitution coefficient e
#
# The piston – connecting rod – crankshaft engine of Awrejcewicz & Kudra (a single-cylinder
# four-stroke engine as an inverted triple pendulum; the piston moves in the cylinder with
# a backlash and hits its wall, "piston slap"). The paper shows two restitution
# coefficients at the cylinder diameter D = 80.04 mm (40 µm of diametral clearance):
#
# * **e = 0** (Fig. 2): "the piston moves six times from one side of the cylinder to the
#   second side during one cycle", adjoining one side most of the time and crossing over
#   with a small rotation, losing contact on the way;
# * **e = 0.9** (Fig. 3): still a tendency to slide six times per cycle, but "multiple
#   impacts between the piston and the cylinder occur before each of the sliding state",
#   and before settling on one side the piston may "rapidly leave the contact and transit
#   into the other side".
#
# Here e runs over [0, 1] on the same engine. For every e the engine runs a transient
# cycle and then the analyzed cycles (720° of crank angle each, from firing TDC), and we
# count per cycle the **side changes**, the **impacts** (all four piston corners), the
# **kinetic energy dissipated at the impacts** and the **mean crank speed** of the
# analyzed cycles (not the engine's own steady speed, which takes thousands of cycles to
# reach: see `benchmarks/steady_speed.py` and docs/piston_accuracy.md). The same
# runs also sample the pin's lateral position x_O3 and the piston tilt φ3 once per cycle
# at fixed crank angles: a Poincaré section of the self-excited engine, drawn against e
# like a bifurcation diagram.
#
# The numbers come from `moreau.problems.piston.study.piston_point`, run over the grid by
# `moreau.sweeps.sweep` on all cores; every finished point is kept in `data/*.parts/`, so
# re-running this notebook only computes what is missing. As in the main job
# (`moreau piston`), drift control is on for every e (`PistonModel.drift_control()`, a
# `moreau.CombinedProjection`): corners in persistent contact are projected back onto the
# cylinder with their velocities made consistent, and restitution acts only at impacts.
# `MOREAU_NOTEBOOK_SCALE=small` runs a reduced version (3 values of e, 2 cycles,
# h = 1e-3) for the test suite.

# %%
import os
import time

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from moreau.problems.piston.study import (
    DEFAULT_ANGLES_DEG,
    piston_cache_key,
    piston_point,
    plot_section,
    plot_side_change_angles,
    plot_sweep,
    section_long,
)
from moreau.sweeps import sweep

SMALL = os.environ.get("MOREAU_NOTEBOOK_SCALE", "full") == "small"
HERE = "." if os.path.basename(os.getcwd()) == "notebooks" else "notebooks"
FIG_DIR = os.environ.get("MOREAU_FIGURES_DIR", os.path.join(HERE, "figures"))
DATA_DIR = os.environ.get("MOREAU_NOTEBOOK_DATA", os.path.join(HERE, "data"))
os.makedirs(FIG_DIR, exist_ok=True)
os.makedirs(DATA_DIR, exist_ok=True)

D_MM = 80.04
if SMALL:
    E = [0.0, 0.5, 0.9]
    RUN = dict(D_mm=D_MM, cycles=1, transient=1, h=1e-3, drift_control=True)
else:
    E = [round(float(x), 6) for x in np.linspace(0.0, 1.0, 21)]
    RUN = dict(D_mm=D_MM, cycles=5, transient=1, h=3e-4, drift_control=True)
SECTION_DEG = list(DEFAULT_ANGLES_DEG)  # crank angles of the once-per-cycle section
tag = "small" if SMALL else "full"
pd.set_option("display.width", 160)
print(f"{len(E)} values of e; per point {RUN['transient']} + {RUN['cycles']} cycles at h = {RUN['h']:g}; "
      f"section at {SECTION_DEG} deg; figures in {FIG_DIR}")

# %% [markdown]
# ## The sweep over e
#
# One row per value of e; the per-cycle lists (`side_changes`, `impacts`, `energy_lost_J`,
# ...) hold one entry per analyzed cycle. `max_penetration_ratio` is the numerical
# penetration of the corners into the wall divided by the clearance: below 0.004 for every
# e (the engine's drift control projects the corners of every restitution back onto the
# wall, accepting 1e-4 of the clearance; the step's own O(h²) drift is what remains).

# %%
t0 = time.perf_counter()
grid = {"e": E, **RUN, "section_deg": tuple(SECTION_DEG)}  # a tuple is one value: the same angles for all
runs = sweep(piston_point, grid, out=os.path.join(DATA_DIR, f"restitution_{tag}.parquet"), progress=not SMALL,
             cache_key=piston_cache_key())  # recomputed when the model or the engine changes
print(f"sweep: {time.perf_counter() - t0:.1f} s wall, {runs['wall_time_s'].sum():.0f} s of simulation")
assert runs["error"].isna().all(), runs.loc[runs["error"].notna(), ["e", "error"]]
runs[["e", "side_changes", "slaps_mean", "impacts_mean", "energy_lost_J_mean", "flight_deg_mean", "mean_speed_rpm",
      "settled_speed_rpm", "max_penetration_ratio", "wall_time_s"]]

# %%
fig = plot_sweep(runs, "e", "restitution e", title=f"D = {D_MM} mm (clearance 40 µm), h = {RUN['h']:g}")
fig.savefig(os.path.join(FIG_DIR, "restitution_sweep.png"), dpi=110)
plt.show()

# %% [markdown]
# **What is seen** (full size: 21 values of e, 5 analyzed cycles each, h = 3e-4).
#
# * **Side changes.** For e = 0 the engine reproduces the paper's Fig. 2: exactly six
#   side changes in every cycle, at the same crank angles from cycle to cycle. The six
#   stages survive up to e = 0.85 — every analyzed cycle of every e in [0, 0.85] has
#   exactly six. At e = 0.9 quick transits appear (8 side changes in every cycle): a
#   bouncing piston leaves the new wall, touches the old one and comes back, the paper's
#   "before the piston stabilizes its motion at one cylinder side, it rapidly leaves the
#   contact and transits into the other side". At e = 0.95 there are 10–12, and at e = 1
#   (no dissipation at the wall) the piston never settles: from 14 to 62 side changes, a
#   different number in every cycle.
# * **Impacts.** The impacts (contact onsets after a flight of 2 % of the clearance) grow
#   steadily with e, from 12 per cycle for e ≤ 0.15 (each of the six crossings lands on
#   one corner, then the tilt brings the other one down) to 18 at e = 0.2, 33 at 0.5, 64
#   at 0.7, 109 at 0.85, 152 at 0.9 and 259 at 0.95: each crossing ends in a longer train
#   of bounces. Here all of them but one (in one cycle at e = 0.95) are slaps (at least
#   1 % of the cycle's largest impulse): the dashed line of all logged impacts lies on the
#   slaps'.
# * **Energy.** The kinetic energy dissipated at the impacts hardly depends on e: 0.042 J
#   per cycle at e = 0, 0.041–0.043 J up to e = 0.7 (with a dip to 0.038 J at e = 0.1 and
#   0.15 that we have not analysed), 0.044–0.050 J from 0.75 to 0.95; only at e = 1 does it
#   vanish (exactly, as it must). Whenever the piston comes to rest against the wall, the
#   whole normal kinetic energy it arrived with is gone — in one plastic slap at e = 0,
#   or over a bounce train at larger e, Σₖ (1 − e²) e²ᵏ = 1. (A projection of the plastic
#   rows only, the earlier default, left the sliding piston 27 % of the clearance inside
#   the wall at e = 0.05 and put a spurious step from 0.043 to 0.054 J between e = 0 and
#   0.05.) The largest single impulse, in contrast, grows with e, roughly like (1 + e):
#   0.114 N s at e = 0, 0.162 N s at 0.5, 0.236 N s at 0.9.
# * **Mean speed of the analyzed cycles.** 2005.79 rpm for every e, to within 0.01 rpm:
#   the slap energy is a few 10⁻⁴ of the ≈ 123 J of brake work per cycle (9.807 N m × 4π).
#   Over a few cycles the speed only repeats the start; where the engine settles (about
#   1997 rpm for e = 0 as h → 0) takes thousands of cycles (docs/piston_accuracy.md).

# %%
fig = plot_side_change_angles(runs, "e", "restitution e", title="Where the piston changes sides")
fig.savefig(os.path.join(FIG_DIR, "restitution_side_change_angles.png"), dpi=110)
plt.show()

# %% [markdown]
# The six crossings sit at fixed crank angles — 9° (just after firing TDC: the gas force
# tilts the rod and throws the piston across), 195° (start of the exhaust stroke), 326°
# and 377° (a quick pair around the exhaust–intake TDC), 428° (intake) and 555° (start of
# compression) — and do not move with e up to 0.7 (to the degree; the crossing at 377°
# moves to 369–376° at 0.75–0.85, the one at 428° to 425–427° at 0.8–0.85): they are where
# the side force of the rod on the pin changes sign, a property of the crank mechanism and
# the pressure curve, not of the wall. At 0.9–0.95 the extra points are the quick
# transits: at 0.9 around the exhaust–intake TDC where the side force is weakest (335°,
# 339° and 362°), at 0.95 after the other crossings instead (14°, 202–204° and 562–564°);
# at e = 1 they are anywhere. The lower panel is the crank angle per cycle during which
# no corner touches the wall: from 92° at e = 0 it grows steadily — a bouncing piston
# spends its time between impacts — to 350° at 0.9, 493° at 0.95 and 626° at e = 1.

# %% [markdown]
# ## A bifurcation-like diagram
#
# The engine is autonomous (self-excited: the gas force depends on the crank angle, not
# on time), so a natural Poincaré section is φ1 = const (mod 720°). For each e the runs
# above sampled x_O3 (in half-clearances: ±1 is an untilted piston against the
# right/left wall) and the tilt φ3 once per analyzed cycle at two crank angles — 60° after
# firing TDC (the piston pressed on the thrust side by the gas) and 420° (early intake,
# light load, where the piston crosses). One dot per e means the motion repeats every
# cycle (period-1); a vertical spread of dots means it does not. (For longer sections
# without the per-cycle figures, `study.bifurcation_samples` does the sampling alone.)

# %%
long = section_long(runs, "e")
spread = long.groupby(["e", "angle_deg"])["x_O3"].agg(lambda v: v.max() - v.min()).unstack()
spread.columns = [f"x_O3 spread at {a:g}°" for a in spread.columns]
spread.T

# %%
fig = plot_section(long, "e", "restitution e", title=f"Section φ1 = const (mod 720°), {RUN['cycles']} cycles per e")
fig.savefig(os.path.join(FIG_DIR, "restitution_bifurcation.png"), dpi=110)
plt.show()

# %% [markdown]
# **What is seen.** At 60° the piston is pinned against the thrust wall by the gas force
# for every e up to 0.9 (x_O3 = −1): a single point. At 420° the sample is a single point
# as well up to e = 0.65 (spread over the cycles below 0.02 half-clearances) and nearly one
# up to 0.85 (0.02–0.11): the motion is period-1, repeating every engine cycle, and the
# point moves as the bounce trains lengthen past e = 0.7 and delay the crossing. At e = 0.9
# the dots spread over 0.33 half-clearances at 420° although every cycle still has 8 side
# changes; at e = 0.95 the spread reaches the 60° section too (0.24; 0.34 at 420°), and at
# e = 1 the dots fill the clearance (0.78 and 1.23): the motion
# no longer repeats. In the language of impact oscillators, growing restitution takes
# the period-1 "six-stage" motion, between e = 0.85 and 0.9, into non-repeating
# (chattering, likely chaotic) motion, which becomes irregular rattling at e = 1; the
# paper shows only e = 0 and 0.9 and does not analyse the transition. Five cycles per e
# tell a repeating motion from a non-repeating one; a finer picture of the transition
# needs more cycles and values of e (`study.bifurcation_samples`).

# %% [markdown]
# ## What it means for an engine designer
#
# * The six slaps per cycle are robust: they are set by the sign changes of the side
#   force of the rod on the pin (gas and inertia forces), not by the wall, and their crank
#   angles do not move with e.
# * The restitution of the piston–liner contact (in a real engine, mostly the squeeze
#   damping of the oil film) sets **how many** impacts make up each slap, not how many
#   slaps there are — and hardly how much energy goes into the wall: the lateral kinetic
#   energy of each crossing is dissipated whatever e < 1. A well-damped contact delivers
#   it in one blow per crossing; a lively one in a first blow up to twice as hard (the
#   impulse grows like 1 + e) followed by tens to hundreds of smaller impacts — a
#   different noise spectrum for about the same energy. Above e ≈ 0.9 the piston stops
#   settling, crosses back and forth and rattles irregularly.
# * The energy dissipated at the impacts is a few 10⁻⁴ of the brake work and does not change
#   the speed: piston slap matters for noise, liner vibration and cavitation, not for the
#   power balance.
# * Caveats: the model has no piston rings, no friction and no oil film, and the
#   pressure curve is synthetic (see `paper_figures.py`); the trends with e are the
#   message, not the exact counts.
