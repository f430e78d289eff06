"""The piston – connecting rod – crankshaft engine of Awrejcewicz & Kudra.

* :mod:`.params` — parameters (SI, the paper's defaults) and the closed form eq. (2.1)–(2.3);
* :mod:`.pressure` — the synthetic four-stroke pressure curve and its K = 25 Fourier series
  (parts in :mod:`~moreau.problems.piston.geometry`, :mod:`~moreau.problems.piston.pressure_curve`,
  :mod:`~moreau.problems.piston.fourier_fit`, :mod:`~moreau.problems.piston.calibration`);
* :mod:`.model` — the moreau scene (:func:`piston_model`);
* :mod:`.analysis` — crank angle, pin position, sides, slaps, cycles, mean and settled speed;
* :mod:`.job`, :mod:`.study`, :mod:`.figures` — the main job, sweep studies, their figures.
"""

from .analysis import cycle_figures, mean_speed_rpm, settled_speed_rpm, side_changes, steady_speed_rpm
from .model import CORNERS, EFFECTS, PistonModel, piston_model
from .params import PistonParameters, closed_form, groups

__all__ = [
    "CORNERS", "EFFECTS", "PistonModel", "PistonParameters", "closed_form", "cycle_figures",
    "groups", "mean_speed_rpm", "piston_model", "settled_speed_rpm", "side_changes",
    "steady_speed_rpm",  # deprecated name of mean_speed_rpm
]
