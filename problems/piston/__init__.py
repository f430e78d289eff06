"""The piston – connecting rod – crankshaft engine of Awrejcewicz & Kudra.

* :mod:`.params` — parameters (SI, the paper's defaults) and the closed form eq. (2.1)–(2.3);
* :mod:`.pressure` — the synthetic four-stroke pressure curve and its K = 25 Fourier series;
* :mod:`.model` — the moreau scene (:func:`piston_model`);
* :mod:`.analysis` — crank angle, pin position, sides, slaps, cycles, speed.
"""

from .analysis import cycle_figures, side_changes, steady_speed_rpm
from .model import CORNERS, EFFECTS, PistonModel, piston_model
from .params import PistonParameters, closed_form, groups

__all__ = [
    "CORNERS", "EFFECTS", "PistonModel", "PistonParameters", "closed_form", "cycle_figures",
    "groups", "piston_model", "side_changes", "steady_speed_rpm",
]
