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
# # The paper's Figs. 2–4, reproduced
#
# Awrejcewicz & Kudra show three responses of their piston – connecting rod – crankshaft
# engine over one 720° cycle, as the non-dimensional position of the piston pin O3
# (x_O3, y_O3) against the crank angle:
#
# | figure | e | D | what the paper reports |
# |---|---|---|---|
# | 2 | 0 | 80.04 mm | six moves from one side of the cylinder to the other per cycle; most of the time the piston adjoins one side; it loses contact while crossing, with a small rotation |
# | 3 | 0.9 | 80.04 mm | still a tendency to slide six times per cycle, but multiple impacts before each sliding state, and quick transits to the other side before the piston stabilizes |
# | 4 | 0.9 | 80.2 mm | the same with the larger backlash |
#
# We run the same three cases with `moreau.problems.piston.job.run_case` (the `moreau piston`
# job: one transient cycle discarded, then the analyzed cycles) and draw the last cycle
# with `moreau.problems.piston.figures.plot_cycle`: x_O3 in half-clearances (±1 = an untilted
# piston against the right/left wall), y_O3 in crank radii l1, the tilt φ3, and which
# corner carries a contact impulse; dotted lines mark the side changes.

# %%
import os

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import moreau as mo
from moreau.problems.piston import PistonParameters, cycle_figures
from moreau.problems.piston.analysis import sliding_phases
from moreau.problems.piston.figures import plot_cycle
from moreau.problems.piston.job import PAPER_CASES, Case, run_cases
from moreau.problems.piston.study import SLAP_FRACTION

SMALL = os.environ.get("MOREAU_NOTEBOOK_SCALE", "full") == "small"
HERE = "." if os.path.basename(os.getcwd()) == "notebooks" else "notebooks"
FIG_DIR = os.environ.get("MOREAU_FIGURES_DIR", os.path.join(HERE, "figures"))
DATA_DIR = os.environ.get("MOREAU_NOTEBOOK_DATA", os.path.join(HERE, "data"))
OUT = os.path.join(DATA_DIR, "paper_small" if SMALL else "paper_full")
os.makedirs(FIG_DIR, exist_ok=True)

H, TRANSIENT, CYCLES = (1e-3, 1, 1) if SMALL else (1e-4, 1, 3)
cases = [Case(e=e, D=D, h=H, cycles=CYCLES, transient=TRANSIENT) for e, D in PAPER_CASES]
rows = run_cases(cases, OUT, progress=False)
summary = pd.DataFrame(rows)
summary[["e", "D_mm", "h", "cycles", "mean_speed_rpm", "settled_speed_rpm", "side_changes_per_cycle",
         "side_change_angles_deg", "impacts_per_cycle",
         "energy_lost_per_cycle_J", "max_penetration_over_clearance", "wall_time_s"]]

# %%
trajs = {c.label: mo.load(os.path.join(OUT, f"piston_{c.label}.npz")) for c in cases}
phase_rows, last_rows = [], []
for fig_no, c in zip((2, 3, 4), cases):
    traj = trajs[c.label]
    params = PistonParameters(e=c.e, D=c.D)
    last = cycle_figures(traj, params)[-1]
    imp_cycle = np.floor(np.interp(traj.impacts.times(), traj.t, traj.q[:, 0]) / (4 * np.pi))
    P = traj.impacts.impulse[imp_cycle == last.cycle]
    last_rows.append({"figure": fig_no, "e": c.e, "D_mm": round(1e3 * c.D, 2), "side_changes": last.side_changes,
                      "angles_deg": " ".join(f"{a:.0f}" for a in last.change_angles_deg),
                      "impacts": last.impacts, "slaps (≥ 1 % of max impulse)": int((P >= SLAP_FRACTION * P.max()).sum()),
                      "largest impulse (N s)": round(last.max_impulse, 3), "energy lost (J)": round(last.energy_lost, 4)})
    fig = plot_cycle(traj, params, last.cycle,
                     title=f"like the paper's Fig. {fig_no}: e = {c.e:g}, D = {1e3 * c.D:.2f} mm — "
                           f"{last.side_changes} side changes, {last.impacts} impacts")
    fig.savefig(os.path.join(FIG_DIR, f"paper_fig{fig_no}.png"), dpi=110)
    plt.show()
    for s in sliding_phases(traj, min_deg=5.0):
        if np.floor(traj.q[s.start, 0] / (4 * np.pi)) == last.cycle:
            phase_rows.append({"figure": fig_no, "e": c.e, "D_mm": round(1e3 * c.D, 2),
                               "wall": "right" if s.side > 0 else "left", "from_deg": round(s.start_deg),
                               "to_deg": round(s.end_deg), "impacts_before": s.impacts_before})
phases = pd.DataFrame(phase_rows)
pd.DataFrame(last_rows).set_index("figure")

# %% [markdown]
# The last analyzed cycle of each case: side changes and their crank angles, all logged
# impacts, and the *slaps* — impacts carrying at least 1 % of the cycle's largest
# impulse; the rest are micro-impacts of a piston settling on a wall, whose number
# depends on the numerics. Below, the sliding phases of that cycle (one wall alone
# carrying the piston for at least 5° of crank angle) and the impacts on that wall since
# the previous phase.

# %%
phases

# %%
per_fig = phases.groupby("figure").agg(phases=("wall", "size"), impacts_before_min=("impacts_before", "min"),
                                       impacts_before_median=("impacts_before", "median"))
per_fig

# %% [markdown]
# ## What matches
#
# (Numbers from the full-size run: h = 1e-4, one transient and three analyzed cycles.)
#
# * **Fig. 2 (e = 0, D = 80.04 mm).** Six side changes in every cycle, at the same crank
#   angles from cycle to cycle (9°, 195°, 326°, 377°, 428° and 555° from firing TDC), and
#   six sliding phases, each entered with a single slap: the paper's "six stages of the
#   piston sliding along the cylinder surface per cycle". Most of the time the piston
#   adjoins one wall with both corners (x_O3 = ±1) and it crosses over in flight with a
#   small tilt (a fraction of a milliradian) — the paper's observation, against Sygniewicz
#   (1999), that the piston loses contact while crossing. The mean speed over the cycles is
#   2005.8 rpm: the runs start at the paper's 2000 rpm, and the engine's own speed relaxes
#   over thousands of cycles (docs/piston_accuracy.md).
# * **Fig. 3 (e = 0.9, D = 80.04 mm).** Every sliding phase is preceded by a train of
#   impacts on the same wall (about 80 in the last cycle), and there are ten side
#   changes per cycle instead of six: the six stages plus two quick round trips across
#   the clearance around the exhaust–intake TDC (334–369°), where the piston "rapidly
#   leaves the contact and transits into the other side" before it stabilizes.
# * **Fig. 4 (e = 0.9, D = 80.2 mm).** The six crossings are there (six side changes in
#   every cycle, at 15°, 206°, 333°, 356°, 433° and 565°), each followed by a long bounce
#   train of large lateral excursions.

# ## What differs, and why
#
# * **The crank angles of the crossings.** Ours follow from a *synthetic* pressure curve
#   (single-zone Wiebe heat release and polytropic compression/expansion, fitted with the
#   paper's K = 25 Fourier series and calibrated so that the self-excited engine runs at
#   2000 rpm with the paper's brake moment; `problems/piston/pressure.py`). The paper
#   used measured data from Sygniewicz (1999), which are not public. The side force on
#   the piston changes sign where the gas force and the inertia forces balance, so the
#   crossing angles near the pressure peak depend on the shape of the curve; the paper
#   itself finds its angles up to 35° away from Sygniewicz's. We cannot compare angle by
#   angle because the paper's figures are only available as pictures.
# * **The axes.** The paper plots x_O3 and y_O3 in its own non-dimensional units; we
#   scale x_O3 by the half-clearance so that ±1 means "against the wall" whatever D is,
#   and add the tilt and the contacts, which the paper describes in words.
# * **The sliding at large clearance.** For Fig. 4 the paper reports the tendency "to
#   slide six times along the cylinder per one cycle". Here, with five times the
#   clearance, the bounce trains are so long that only two phases per cycle have one wall
#   carrying the piston for more than 5° of crank angle; between them the piston bounces
#   towards a wall without settling (see `clearance.py`: the time in flight grows with
#   the gap). A restitution coefficient is a crude model of an oil-lubricated contact,
#   as the paper says itself, and the count is sensitive to it.
# * **The count of side changes at e = 0.9** depends on how quick transits are counted:
#   here every arrival on the other wall counts (see `moreau.problems.piston.analysis`), so a
#   bounce across and back counts twice, as the paper describes it; the paper does not
#   give a number.
# * **The count of impacts** (hundreds to thousands per cycle at e = 0.9) includes
#   micro-impacts of a piston settling on a wall whose number depends on the numerics;
#   the slaps (≥ 1 % of the cycle's largest impulse), the side changes, their angles,
#   the speed and the energy lost at the impacts are the robust figures.
# * **Numerics.** The paper does not say how its impacts were integrated (a
#   restitution rule at each impact, by its wording); we use the Moreau–Jean
#   time-stepping scheme at h = 1e-4 (≈ 0.006° of crank angle) with the positions
#   projected back onto the cylinder after each step, so the corners stay out of the wall
#   (`max_penetration_over_clearance` above).
#
# ## For an engine designer
#
# The model reproduces the qualitative behaviour the paper reports — six slaps per cycle
# at crank angles fixed by the crank mechanism and the pressure curve, and, with little
# damping at the wall, bounce trains and quick transits — from the published parameters
# alone. Quantitative slap timing needs the engine's real pressure trace, which is one
# argument (`pressure=`) of `moreau.problems.piston.piston_model`.
